"""Regression test: a fresh main job on HOMER+ gives the committed reference results.

The LLM-free half of ``globe reproduce`` (the model selections, the baseline, n-gram, smoothed
and routine rows of Table I, calibration, activity anticipation, the lookahead and the fetch policy
with their baseline and oracle rows and the fetch policy's source, and missing labels) is run,
its printed tables checked whole when piped, and its files compared row by row with
``reference/homer_plus``: choices exactly, figures to the third decimal. Ties in every selection
are broken by an explicit order, so a changed last bit cannot flip a row; a row that moves is a
change to explain (and to commit with new reference results).
"""

from __future__ import annotations

import csv
import math
import subprocess
import sys
from pathlib import Path

import pytest

REFERENCE = Path(__file__).resolve().parents[2] / "reference" / "homer_plus"
METHODS = ("persistence", "ngram", "ngram_smoothed", "routine")  # run; the baselines' rows come with them
COMPARED = (*METHODS, "time_of_day", "hour_activity", "oracle")  # the oracle: the lookahead's and fetch policy's
#: file -> the columns that name a row (every other column is a result)
KEYS = {
    "selection.csv": ("method", "household", "part", "params", "criterion"),
    "table1.csv": ("method", "household", "average"),
    "details.csv": ("method", "household"),
    "calibration.csv": ("method",),
    "activity_anticipation.csv": ("household", "method", "horizon_min"),
    "next_activity.csv": ("household", "method"),
    "lookahead.csv": ("method", "household", "horizon_min"),
    "lookahead_selection.csv": ("method", "household", "run_end", "run_memory", "run_next", "horizon_min",
                                "threshold", "objects"),
    "fetch_policy.csv": ("method", "household", "cost_ratio", "configured"),
    "fetch_selection.csv": ("method", "household", "objects"),
    "fetch_lead_times.csv": ("household", "lead_min"),
    "missing_labels.csv": ("method", "household", "labels_pct"),
    "missing_labels_selection.csv": ("household", "params"),
}
BASELINES = ("time_of_day", "hour", "CV")  # the activity ahead's rules beside the models ("hour + activity", ...)
IGNORED = {"seconds"}  # wall-clock figures
TOLERANCE = 5e-4 + 1e-9  # the files keep four decimals: equal to the third decimal


def _rows(path: Path, keys: tuple[str, ...]) -> dict[tuple[str, ...], dict[str, str]]:
    with path.open(newline="") as fh:
        return {tuple(row[k] for k in keys): row for row in csv.DictReader(fh)}


def _differences(name: str, fresh: dict, reference: dict, keys: tuple[str, ...]) -> list[str]:
    out, compared = [], 0
    for key, ref in reference.items():
        method = dict(zip(keys, key)).get("method", METHODS[0]).split(" ")[0]
        if method not in COMPARED and not method.startswith("chosen") and method not in BASELINES:
            continue  # an LLM method's row: not run here
        row = fresh.get(key)
        compared += 1
        if row is None:
            out.append(f"{name}: row {key} missing")
            continue
        for column, want in ref.items():
            if column in keys or column in IGNORED:
                continue
            got = row.get(column)
            try:
                same = math.isclose(float(got), float(want), rel_tol=0.0, abs_tol=TOLERANCE)  # type: ignore[arg-type]
            except (TypeError, ValueError):
                same = got == want
            if not same:
                out.append(f"{name} {key} {column}: {want} -> {got}")
    return out if compared else [f"{name}: no reference row compared"]


@pytest.mark.slow
def test_main_job_matches_the_reference_results(tmp_path: Path) -> None:
    config = tmp_path / "globe.toml"
    config.write_text("[evaluation]\nmethods = [" + ", ".join(f'"{m}"' for m in METHODS) + "]\n")
    out = tmp_path / "results"
    done = subprocess.run([sys.executable, "-m", "globe", "reproduce", "--out", str(out), "--config", str(config),
                           "--backend", "none", "--no-robustness"], capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr[-3000:]
    # the tables printed to a pipe (not a terminal) are whole: no cell cut short with an ellipsis
    assert "Persistence" in done.stdout and "n-gram Markov" in done.stdout and "…" not in done.stdout
    differences = []
    for name, keys in KEYS.items():
        differences += _differences(name, _rows(out / name, keys), _rows(REFERENCE / name, keys), keys)
    assert not differences, "results moved against reference/homer_plus:\n" + "\n".join(differences[:40])
