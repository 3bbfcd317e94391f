"""The inference engine's main costs, against another version of GLOBE in the same run.

Times, per household and on one core (``evaluation.workers = 1``), the work the main job spends
its LLM-free time on: the model selection of both families (cross-validation on training days),
the lookahead of every method (its settings chosen by cross-validation, then the test days), the
activity 1..k steps ahead (the routine model's beam over every test step, and the folds of its
mix with the time of day) and the missing-label runs (the filter's movement evidence chosen by
cross-validation, then every label share with its lookahead). A part a version lacks prints nan
and stays out of the totals. Each part runs in a fresh process, for this checkout and, with
``--baseline DIR`` (another checkout, e.g. ``git worktree add /tmp/before HEAD~1``, built with
``pip install -e`` or with its compiled modules beside its sources), for that one too, alternating
``--repeat`` times; the best time of each is printed with the ratio. Usage:
python benchmarks/bench_engine.py [--baseline DIR] [--households A,B,C] [--repeat 2]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
from pathlib import Path

from globe.data.locate import resolve_data_root
from globe.errors import DataError

ROOT = Path(__file__).resolve().parent.parent

PART = """
import json, sys, time
from globe.config import GlobeConfig
from globe.data.csv_logs import load_household
from globe.data.locate import resolve_data_root
from globe.evaluation import lookahead, missing_labels
from globe.evaluation.anticipation import method_models
from globe.evaluation.tuning import tuned_models

try:  # the memo of this version (an older one passed a dict)
    from globe.evaluation.selection import Memo
except ImportError:
    Memo = dict
part, name, data = sys.argv[1], sys.argv[2], sys.argv[3]
cfg = GlobeConfig(evaluation={"workers": 1})
household = load_household(resolve_data_root(data), name)
cache = Memo()
if part != "selection":  # what the main job has chosen before these stages
    for family in ("witten_bell", "routine"):
        tuned_models(household, cfg, family, cache)
started = time.perf_counter()
if part == "selection":
    for family in ("witten_bell", "routine"):
        tuned_models(household, cfg, family, cache)
elif part == "lookahead":
    for method in cfg.lookahead.methods:
        lookahead.evaluate_lookahead(household, cfg, method_models(method, household, cfg, cache), method, cache)
elif part == "activity_ahead":
    try:  # the activity 1..k steps ahead (a version without this stage times nothing)
        from globe.evaluation.activity_anticipation import run_activity_anticipation
    except ImportError:
        print(json.dumps(None))
        sys.exit()
    run_activity_anticipation(cfg, [household], cache)
else:
    missing_labels.run_missing_labels(cfg, [household], None, cache)
print(json.dumps(time.perf_counter() - started))
"""

PARTS = ("selection", "lookahead", "activity_ahead", "missing_labels")


def timed(source: Path, part: str, household: str, data: str) -> float:
    """Seconds of one part in a fresh process running the GLOBE of ``source`` (a checkout); NaN
    where that version has no such part."""
    env = dict(os.environ, PYTHONPATH=str(source / "src"))
    out = subprocess.run([sys.executable, "-c", PART, part, household, data], env=env,
                         capture_output=True, text=True)
    if out.returncode:
        raise SystemExit(f"{part} of household {household} failed in {source}:\n{out.stderr[-3000:]}")
    seconds = json.loads(out.stdout.strip().splitlines()[-1])
    return math.nan if seconds is None else float(seconds)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--data", default=None, help="HOMER+ folder (else $GLOBE_DATA, else ../shared/data/homer_plus)")
    parser.add_argument("--baseline", default=None, help="another GLOBE checkout to time beside this one")
    parser.add_argument("--households", default="A,B,C")
    parser.add_argument("--repeat", type=int, default=2, help="runs of each part and version (the best counts)")
    args = parser.parse_args()
    try:  # one folder for both versions (a checkout elsewhere has no ../shared beside it)
        data = str(resolve_data_root(args.data))
    except DataError as e:
        raise SystemExit(str(e)) from None
    versions = {"this": ROOT} | ({"baseline": Path(args.baseline).resolve()} if args.baseline else {})
    print(f"{'part':16s} {'home':5s}" + "".join(f"{v + ' s':>12s}" for v in versions)
          + (f"{'ratio':>8s}" if args.baseline else ""))
    totals = {v: 0.0 for v in versions}
    for part in PARTS:
        for household in args.households.split(","):
            best = {v: float("inf") for v in versions}
            for _ in range(args.repeat):  # alternating, so both see the machine in the same state
                for v, src in versions.items():
                    seconds = timed(src, part, household, data)
                    best[v] = seconds if math.isnan(seconds) else min(best[v], seconds)
            both = not any(math.isnan(b) for b in best.values())  # the totals: parts both versions have
            for v in versions:
                totals[v] += best[v] if both else 0.0
            ratio = (f"{best['this'] / best['baseline']:7.2f}x" if both else f"{'-':>8s}") if args.baseline else ""
            print(f"{part:16s} {household:5s}" + "".join(f"{best[v]:12.2f}" for v in versions) + ratio)
    ratio = f"{totals['this'] / totals['baseline']:7.2f}x" if args.baseline else ""
    print(f"{'all':16s} {'':5s}" + "".join(f"{totals[v]:12.2f}" for v in versions) + ratio)


if __name__ == "__main__":
    main()
