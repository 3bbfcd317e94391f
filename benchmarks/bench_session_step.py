"""A household session's step as the service runs it, against another version of GLOBE in the same run.

On the simulated sensor home (tests/simulated_sensors.py: 21 labelled days, its test days lived
with their sensors and no label), a session is built as ``POST /households`` builds one (the
clock model as the dynamics, the recogniser's default settings, no questions; fixed, so every
version runs the same models; ``--settings`` for others, such as the evidence on changes) and
each step is timed as the service serves it: the observation
taken in, the activity recognised, the decision (next activity, object, fetches) read. Printed
per step size (10 and 1 minutes): milliseconds per step over the test days after the first
(recognising: the observation and the recognised activity; deciding: the decision), for
this checkout and, with ``--baseline DIR`` (another checkout, e.g. ``git worktree add
/tmp/before HEAD~1``, built with ``pip install -e`` or with its compiled modules beside its
sources), for that one too, each in a fresh process, alternating ``--repeat`` times; the best of
each and their ratio. The issue's target: recognition within 1 ms a step per household.
Usage: python benchmarks/bench_session_step.py [--baseline DIR] [--repeat 3] [--steps 10,1] [--settings JSON]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

PART = """
import json, sys, time
from dataclasses import replace
from globe.config import GlobeConfig
from globe.evaluation.deploy import choose_deployment
from globe.evaluation.online import day_observations
from globe.recognition.recogniser import RecognitionSettings
from globe.session import build_session
from tests.simulated_sensors import sensor_home
import datetime as dt

step = int(sys.argv[1])
settings = RecognitionSettings(**json.loads(sys.argv[2]))
test = 3 if step < 5 else 12  # about the same number of steps timed
home, sensors = sensor_home(days=21 + test, test=test, step=step, seed=0)
config = GlobeConfig().with_overrides({"llm.backend": "none", "models.activity_estimator": "clock"})
deployment = choose_deployment(home, config, method="ngram")  # the [models] section as written: no search
session = build_session(home, config, deployment, None, sensors=sensors, recognition=settings,
                        questions_per_day=0)
first = dt.date(2026, 3, 2)
recognising, deciding, steps = 0.0, 0.0, 0
for i, day in enumerate(home.test):
    seen, said = 0.0, 0.0
    for _, obs in day_observations(home, day, first + dt.timedelta(days=i), visible=lambda _t: False,
                                   sensors=sensors):
        started = time.perf_counter()
        session.observe(obs)
        session.recognised()
        middle = time.perf_counter()
        session.decide()
        seen, said = seen + middle - started, said + time.perf_counter() - middle
    if i:  # the first day warms the caches
        recognising, deciding, steps = recognising + seen, deciding + said, steps + len(day)
print(json.dumps([recognising / steps, deciding / steps]))
"""


def timed(source: Path, step: int, settings: dict) -> tuple[float, float]:
    """Seconds per step (recognising, deciding) in a fresh process running the GLOBE of
    ``source`` (a checkout), its recogniser built with ``settings`` (RecognitionSettings' fields)."""
    env = dict(os.environ, PYTHONPATH=f"{source / 'src'}{os.pathsep}{source}")
    out = subprocess.run([sys.executable, "-c", PART, str(step), json.dumps(settings)], env=env,
                         capture_output=True, text=True, cwd=source)
    if out.returncode:
        raise SystemExit(f"the {step}-minute session of {source} failed:\n{out.stderr[-3000:]}")
    recognising, deciding = json.loads(out.stdout.strip().splitlines()[-1])
    return float(recognising), float(deciding)


def said(seconds: tuple[float, float]) -> str:
    recognising, deciding = seconds
    return (f"{(recognising + deciding) * 1e3:.3f} ms a step (recognising {recognising * 1e3:.3f} ms, "
            f"deciding {deciding * 1e3:.3f} ms)")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--baseline", type=Path, default=None, help="another checkout to time beside this one")
    parser.add_argument("--repeat", type=int, default=3, help="runs of each, alternating (the best is kept)")
    parser.add_argument("--steps", default="10,1", help="step sizes in minutes, comma-separated")
    parser.add_argument("--settings", default="{}", help="the recogniser's settings as JSON (RecognitionSettings' "
                        "fields, default its defaults; every checkout timed must know them), e.g. '{\"edges\": true}'")
    args = parser.parse_args()
    settings = json.loads(args.settings)
    sources = [("this", ROOT)] + ([("baseline", args.baseline.resolve())] if args.baseline else [])
    for step in (int(s) for s in args.steps.split(",")):
        best = {name: (math.inf, math.inf) for name, _ in sources}
        for _ in range(args.repeat):
            for name, source in sources:
                best[name] = min(best[name], timed(source, step, settings), key=sum)
        line = f"{step:>2}-minute steps: {said(best['this'])}"
        if args.baseline:
            ratio = sum(best["baseline"]) / sum(best["this"])
            line += f"; baseline {said(best['baseline'])}: {ratio:.1f}x faster now"
        print(line, flush=True)


if __name__ == "__main__":
    main()
