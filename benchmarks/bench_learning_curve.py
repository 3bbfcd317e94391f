"""Learning curve through the real HTTP service: after 1, 2, 5, 10, 20, 40 and 65 training days,
streamed step by step as observations into a fresh household, score the 10 test days (activity
F1, object F1, fetch precision and recall). See globe.service.learning_curve for the rules.

Starts ``globe serve`` on a free loopback port with a temporary database and an admin token,
writes learning_curve.csv and learning_curve.png into --out, prints the table and the time taken.
The database lives in /dev/shm where there is one: this measures learning, not fsync.
Usage: python benchmarks/bench_learning_curve.py [--out DIR] [--households A,B,C] [--checkpoints 1,2,5]
       [--isolate-up-to 10] [--backend none|embedded] [--config FILE] [--data DIR]
"""

from __future__ import annotations

import csv
import os
import signal
import sys
import tempfile
import time
from pathlib import Path

from common import serve, setup, stop
from globe.evaluation.plots_learning import learning_curve_figure
from globe.service.auth import create_token
from globe.service.client import GlobeClient
from globe.service.learning_curve import (
    CHECKPOINTS,
    COLUMNS,
    ISOLATE_UP_TO,
    CurvePoint,
    learning_curve,
    required_clock_skew,
    table_rows,
)


def _fmt(value: object) -> str:
    return f"{value:.3f}" if isinstance(value, float) else "–" if value is None else str(value)


def main() -> None:
    _, homes, args = setup(__doc__, {
        "--out": {"default": "results/learning_curve", "help": "folder for learning_curve.csv and .png"},
        "--households": {"default": None, "help": "comma-separated subset, e.g. A,B (default: all)"},
        "--checkpoints": {"default": ",".join(map(str, CHECKPOINTS)), "help": "learned training days to score at"},
        "--isolate-up-to": {"type": int, "default": ISOLATE_UP_TO,
                            "help": "checkpoints up to this give each test day its own household (0: never)"},
        "--backend": {"default": "none", "help": "LLM backend of the service: none (default, fast) or embedded"},
        "--config": {"default": None, "help": "TOML configuration passed to globe serve"},
    })
    checkpoints = [int(k) for k in args.checkpoints.split(",") if k.strip()]
    if args.households:
        wanted = {h.strip() for h in args.households.split(",")}
        homes = [h for h in homes if h.name in wanted]
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    skew_days = max(required_clock_skew(h, checkpoints).days for h in homes) + 1
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))  # stop the service too when terminated
    started = time.perf_counter()
    points: list[CurvePoint] = []
    with tempfile.TemporaryDirectory(dir="/dev/shm" if os.path.isdir("/dev/shm") else None) as tmp:
        db = Path(tmp) / "globe.sqlite3"
        token = create_token(db, admin=True)
        env = dict(os.environ, GLOBE_SERVICE__MAX_CLOCK_SKEW=f"P{skew_days}D", GLOBE_SERVICE__TIMEZONE="UTC")
        options = ["--backend", args.backend] + (["--config", args.config] if args.config else [])
        proc, url = serve(db, env, *options, log=Path(tmp) / "server.log")
        try:
            with GlobeClient(url, token=token, timeout_s=120) as client:
                for h in homes:
                    def report(p: CurvePoint) -> None:
                        print(f"  {p.household} after {p.days_learned:2d} days: activity F1 {_fmt(p.activity_f1)}, "
                              f"object F1 {_fmt(p.object_f1)}, fetch precision {p.fetch_precision:.3f}, "
                              f"recall {p.fetch_recall:.3f} ({p.observations} observations, {p.elapsed_s:.1f} s)",
                              flush=True)

                    points += learning_curve(client, h, checkpoints, isolate_up_to=args.isolate_up_to, progress=report)
        finally:
            stop(proc)
    elapsed = time.perf_counter() - started
    rows = table_rows(points)
    with (out / "learning_curve.csv").open("w", newline="", encoding="utf-8") as fh:
        writer = csv.DictWriter(fh, fieldnames=COLUMNS)
        writer.writeheader()
        writer.writerows({k: (round(v, 4) if isinstance(v, float) else v) for k, v in r.items()} for r in rows)
    fig = learning_curve_figure(rows)
    fig.savefig(out / "learning_curve.png", dpi=120)
    print()
    print(" ".join(f"{c:>15s}" for c in COLUMNS))
    for r in rows:
        print(" ".join(f"{_fmt(r[c]):>15s}" for c in COLUMNS))
    observations = sum(p.observations for p in points)
    print(f"\n{len(points)} points (a household per test day up to {args.isolate_up_to} days, "
          f"LLM backend {args.backend}), {observations} observations posted: {elapsed:.1f} s "
          f"({1000 * elapsed / max(observations, 1):.2f} ms per observation, predictions included)")
    print(f"wrote {out / 'learning_curve.csv'} and {out / 'learning_curve.png'}")


if __name__ == "__main__":
    main()
