"""The main job end to end: ``globe reproduce`` with an empty LLM answer cache (cold), then again
with the cache it filled (cached); total and per-stage times from each run's ``stages.csv``, and
whether both runs wrote identical tables.

Targets: <= 240 s cold and <= 60 s cached on a quiet 2-core machine.
Usage: python benchmarks/bench_main_job.py [--data DIR] [--keep DIR]
"""

from __future__ import annotations

import argparse
import csv
import filecmp
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

COLD_TARGET_S, CACHED_TARGET_S = 240.0, 60.0
TABLES = ("table1.csv", "details.csv", "selection.csv", "calibration.csv", "robustness/robustness.csv",
          "robustness/consistency.csv", "robustness/ablation_train_level.csv", "robustness/ablation_threshold.csv")


def run(out: Path, cache: Path, data: str | None) -> float:
    env = dict(os.environ, GLOBE_LLM__CACHE_DIR=str(cache))
    cmd = [sys.executable, "-m", "globe", "reproduce", "--out", str(out)] + (["--data", data] if data else [])
    started = time.perf_counter()
    subprocess.run(cmd, env=env, check=True, stdout=subprocess.DEVNULL)
    return time.perf_counter() - started


def stages(out: Path) -> dict[str, float]:
    with (out / "stages.csv").open(newline="") as fh:
        return {r["stage"]: float(r["seconds"]) for r in csv.DictReader(fh)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--data", default=None, help="HOMER+ folder (else $GLOBE_DATA, else ../shared/data/homer_plus)")
    parser.add_argument("--keep", default=None, help="keep both results folders and the LLM answer cache here")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        root = Path(args.keep) if args.keep else Path(tmp)
        cache = root / "cache"
        if cache.exists() and any(cache.iterdir()):
            sys.exit(f"{cache} holds answers already: the cold run needs an empty cache (another --keep folder?)")
        cold_s = run(root / "cold", cache, args.data)
        cached_s = run(root / "cached", cache, args.data)
        cold, cached = stages(root / "cold"), stages(root / "cached")
        print(f"{'stage':44s} {'cold s':>8s} {'cached s':>9s}")
        for name in cold:
            print(f"{name:44s} {cold[name]:8.1f} {cached.get(name, float('nan')):9.1f}")
        print(f"{'wall clock (incl. start-up)':44s} {cold_s:8.1f} {cached_s:9.1f}")
        same = [t for t in TABLES
                if (root / "cold" / t).is_file() and filecmp.cmp(root / "cold" / t, root / "cached" / t, shallow=False)]
        print(f"tables identical cold vs cached: {len(same)}/{len(TABLES)}"
              + ("" if len(same) == len(TABLES) else f" (differ or missing: {sorted(set(TABLES) - set(same))})"))
        print(f"cold {cold_s:.0f} s (target <= {COLD_TARGET_S:.0f}: {'ok' if cold_s <= COLD_TARGET_S else 'MISSED'}); "
              f"cached {cached_s:.0f} s "
              f"(target <= {CACHED_TARGET_S:.0f}: {'ok' if cached_s <= CACHED_TARGET_S else 'MISSED'})")


if __name__ == "__main__":
    main()
