"""The lookahead's and fetch policy's oracle row (the movement model told the true activity) and
the clock-aware object model offered to cross-validation, on simulated homes: a home whose
objects follow the hour and the day of the week, where the clock-aware model must win and beat
the n-gram; a home with no routine of the clock whose objects follow the activity, where it loses
and must not be chosen."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest

from globe.config import GlobeConfig
from globe.evaluation import main_job
from globe.evaluation.docs_tables import fetch_policy, lookahead, lookahead_selection
from globe.evaluation.lookahead import CLOCK, MOVEMENTS, ORACLE, choose_settings
from globe.evaluation.selection import Memo
from globe.models.baselines import ORACLE_LABEL
from tests.simulated import activity_objects_home, clocked_objects_home

CONFIG = GlobeConfig().with_overrides({"llm.backend": "none", "selection.folds": 3,
                                       "lookahead.methods": ("persistence", "ngram", "routine")})


def read(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as fh:
        return list(csv.DictReader(fh))


def chosen(out: Path) -> dict[str, dict[str, str]]:
    return {r["method"]: r for r in read(out / "lookahead_selection.csv") if r["chosen"] == "True"}


@pytest.fixture(scope="module")
def clocked(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("clocked")
    main_job.object_anticipation(CONFIG, [clocked_objects_home()], out)
    return out


def test_where_objects_follow_the_clock_cross_validation_chooses_the_clock_aware_model(clocked):
    picks = chosen(clocked)
    assert picks["routine"]["objects"] == CLOCK  # offered to GLOBE's row, and it won on the training days
    assert picks["ngram"]["objects"] == MOVEMENTS and picks[ORACLE]["objects"] == MOVEMENTS  # never offered
    look = {(r["method"], r["horizon_min"]): float(r["f1"]) for r in read(clocked / "lookahead.csv")
            if r["household"] == "mean"}
    for minutes in ("30", "60"):
        assert look[("routine", minutes)] > look[("ngram", minutes)] + 0.3
        # the activity stays the same all afternoon: knowing it, the movement model still cannot time the uses
        assert look[("routine", minutes)] > look[(ORACLE, minutes)]
    assert "objects: clock-aware model" in lookahead_selection(clocked)
    # the fetch policy's source has its own choice, by what the fetches cost on held-out training days
    costs = {r["objects"]: r for r in read(clocked / "fetch_selection.csv")}
    assert set(costs) == {MOVEMENTS, CLOCK} and {r["method"] for r in costs.values()} == {"routine"}
    assert costs[CLOCK]["chosen"] == "True" and costs[MOVEMENTS]["chosen"] == "False"
    assert float(costs[CLOCK]["cv_cost_per_day"]) < float(costs[MOVEMENTS]["cv_cost_per_day"])


def test_the_oracle_rows_know_the_activity_and_say_they_are_oracles(clocked):
    rows = [r for r in read(clocked / "lookahead.csv") if r["method"] == ORACLE]
    assert rows and all(float(r["activity_accuracy"]) == 1.0 for r in rows)
    assert list(dict.fromkeys(r["method"] for r in read(clocked / "lookahead.csv")))[-1] == ORACLE
    fetch = [r["method"] for r in read(clocked / "fetch_policy.csv") if r["household"] == "all" and
             r["configured"] == "True"]
    assert fetch == ["routine", "hour_activity", ORACLE]
    assert ORACLE_LABEL in lookahead(clocked) and ORACLE_LABEL in fetch_policy(clocked)
    assert {r["household"] for r in read(clocked / "fetch_lead_times.csv")} <= {"ClockedObjects"}


def test_where_objects_follow_the_activity_the_clock_aware_model_loses_and_is_not_chosen():
    home = activity_objects_home()
    selection = choose_settings(home, CONFIG, CONFIG.models, Memo(), objects=(MOVEMENTS, CLOCK))
    assert selection.best["objects"] == MOVEMENTS
    mean = {}
    for params, f1 in selection.scores:
        key = (params["objects"], params["run_end"], params["run_memory"], params["run_next"], params["horizon"])
        mean[key] = max(mean.get(key, 0.0), f1)
    clock = [f for k, f in mean.items() if k[0] == CLOCK]
    best_movements = max(sum(f for k, f in mean.items() if k[:4] == s) / len(clock)
                         for s in {k[:4] for k in mean if k[0] == MOVEMENTS})
    assert sum(clock) / len(clock) < best_movements  # it lost on the training days


def test_the_oracle_is_told_the_activity_that_times_the_uses(tmp_path):
    """Where the activity times every use, the oracle foresees them all: the ceiling the gap is read against."""
    cfg = CONFIG.with_overrides({"lookahead.methods": ("persistence",), "policy.method": "persistence"})
    main_job.object_anticipation(cfg, [activity_objects_home()], tmp_path)
    look = {(r["method"], r["horizon_min"]): float(r["f1"]) for r in read(tmp_path / "lookahead.csv")
            if r["household"] == "mean"}
    assert look[(ORACLE, "30")] > 0.9 and look[(ORACLE, "30")] > look[("persistence", "30")] + 0.3
