"""Activity recognition on the simulated sensor home (tests/simulated_sensors.py): its speed
against the issue's targets, and the figures the closing note reports.

- online: one household's step (sensor features in, the filter updated, the posterior read),
  per step, against the 1 ms target;
- offline: a year of 1-minute steps recognised (filtered) at once, against the one-minute target;
  for naive Bayes, the discriminative emission and naive Bayes with the evidence on changes (edges),
  each one's ratio to naive Bayes's beside it;
- accuracy: the learning curve (1, 3, 7, 14 and all labelled days, settings chosen on them), the
  asking curve from 1 and from 3 labelled days (questions a day spent where worth most, where the
  recogniser is least sure, and at random: the mean of three draws), the library rows (a CRF,
  sklearn-crfsuite, and a plain HMM, hmmlearn, when installed) and GLOBE's activity model fed recognised activities.

New code: there is no previous version to compare with; ratios are to the targets.
Usage: python benchmarks/bench_recognition.py [--quick]
"""

from __future__ import annotations

import argparse
import sys
import time
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from tests.simulated_sensors import sensor_home  # noqa: E402

from globe.evaluation import recognition as R  # noqa: E402
from globe.models.clock import ClockModel  # noqa: E402
from globe.recognition.recogniser import Recogniser, RecognitionSettings  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="speed only, and a 60-day year")
    args = parser.parse_args()
    home, sensors = sensor_home(days=28, test=7, step=1, seed=0)
    days = 60 if args.quick else 365
    year, year_sensors = sensor_home(days=days + 1, test=1, step=1, seed=2)
    steps = sum(len(d) for d in year.train)
    timings: dict[str, tuple[float, float]] = {}
    plain = RecognitionSettings(features=("raw", "change", "last"), weight=0.5)
    variants = {"naive_bayes": plain, "discriminative": replace(plain, emission="discriminative"),
                "naive_bayes + edges": replace(plain, edges=True)}  # naive Bayes first: the others' ratios are to it
    for emission, settings in variants.items():
        rec = Recogniser(settings).fit(home.train, sensors, 1)
        day = home.test[0]
        start = time.perf_counter()
        rec.filter_asking(day, lambda t, p: False, lambda t: None)
        online = (time.perf_counter() - start) / len(day)
        rec_year = Recogniser(settings).fit(year.train[:14], year_sensors, 1)
        start = time.perf_counter()
        rec_year.filter(year.train)
        per_year = (time.perf_counter() - start) * 365 * 1440 / steps
        timings[emission] = (online, per_year)
        ratio = "" if emission == "naive_bayes" else (f"; {online / timings['naive_bayes'][0]:.2f}x and "
                                                       f"{per_year / timings['naive_bayes'][1]:.2f}x naive Bayes's")
        print(f"{emission}: online {online * 1e3:.3f} ms per step per household (target 1 ms: {online * 1e3:.2f}x); "
              f"a year of 1-minute steps (525600) offline in {per_year:.1f} s (target 60 s: {per_year / 60:.2f}x)"
              f"{ratio}")
    if args.quick:
        return
    print("learning curve (test days, online / smoothed):")
    for row in R.learning_curve(home, sensors, 1):
        print(f"  {row['labelled_days']:>2} labelled days: time-slice {row['time_slice_accuracy']:.3f}, "
              f"class {row['class_accuracy']:.3f} / smoothed {row['smoothed_time_slice_accuracy']:.3f}, "
              f"{row['smoothed_class_accuracy']:.3f}  {row['settings']}")
    for labelled_days in (1, 3):
        print(f"asking curve ({labelled_days} labelled days, the other {len(home.train) - labelled_days} lived through "
              "asking; class accuracy on the test days: worth, the chance of being wrong alone, random (mean of "
              f"{R.DRAWS} draws +- sd)):")
        for row in R.asking_curve(home, sensors, 1, labelled_days=labelled_days, asking=("worth", "unsure", "random")):
            gain = row["worth_class_accuracy"] - row["random_class_accuracy"]
            print(f"  {row['questions_per_day']} a day: worth {row['worth_class_accuracy']:.3f} "
                  f"({row['worth_questions']:.0f} asked), unsure {row['unsure_class_accuracy']:.3f}, random "
                  f"{row['random_class_accuracy']:.3f} +- {row.get('random_class_accuracy_sd', 0.0):.3f} "
                  f"({row['random_questions']:.0f} asked); worth - random {gain:+.3f}")
    rows = R.library_rows(home, sensors, 1)
    for name in ("crf (sklearn-crfsuite)", "plain hmm (hmmlearn)"):
        print(f"{name}, every training day, hindsight:", rows[name].row() if name in rows else "not installed")
    chosen = R.fit_recogniser(list(home.train), sensors, 1)
    model = ClockModel(step_minutes=1).fit([d.activities for d in home.train], [d.weekday for d in home.train])
    print("end to end (clock model, all labelled days):", R.end_to_end(model, home.test, chosen.predict(home.test)))


if __name__ == "__main__":
    main()
