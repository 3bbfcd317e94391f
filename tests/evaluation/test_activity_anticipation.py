"""Activity anticipation scored for any home: the model beside persistence, the time-of-day mode
and hour + activity, persistence and hour + activity scored by hand, the per-horizon choice on
training days never behind a baseline, and the files a results folder gets."""

import csv

from globe import assembly
from globe.config import GlobeConfig
from globe.data.records import Day
from globe.evaluation.activity_anticipation import (
    BLEND_WEIGHTS,
    HOUR_ACTIVITY,
    PER_HORIZON,
    blend_weights,
    fold_scores,
    run_activity_anticipation,
    score_anticipation,
    write_activity_anticipation,
)
from globe.evaluation.selection import Memo
from globe.evaluation.tuning import data_folds
from globe.models.baselines import HourActivityBaseline, PersistenceModel
from tests.simulated import clock_home, random_home


def by_method(scores, minutes):
    return {r["method"]: r for r in scores.rows() if r["horizon_min"] == minutes}


def test_persistence_scores_are_the_share_of_steps_that_did_not_change():
    home = clock_home(30, 4, 10, 3)
    model = PersistenceModel().fit([d.activities for d in home.train])
    scores = score_anticipation(home.name, model, home.train, home.test, 3, 10, "model")
    for j in (1, 3):
        refs = [(d, r) for d in home.test for r in range(len(d) - 3)]
        same = sum(d.activities[r] == d.activities[r + j] for d, r in refs) / len(refs)
        rows = by_method(scores, 10 * j)
        assert rows["persistence"]["accuracy"] == round(same, 4)
        assert rows["model"]["accuracy"] == rows["persistence"]["accuracy"]  # the same rule as a model
    assert dict((m, a) for m, (_, a) in scores.next_activity.items())["persistence"] == 0.0


def test_on_a_clock_home_the_chosen_model_beats_both_baselines_further_ahead(tmp_path):
    home = clock_home(75, 10, 10, 4, 3.0)
    [scores] = run_activity_anticipation(GlobeConfig(), [home], Memo())
    for minutes in (30, 60):
        rows = by_method(scores, minutes)
        chosen = next(r for m, r in rows.items() if m.startswith("chosen") and not m.endswith("time of day"))
        assert chosen["accuracy"] > rows["persistence"]["accuracy"] + 0.03
        assert chosen["accuracy"] > rows["time_of_day"]["accuracy"] + 0.03
        assert chosen["log_loss"] < rows["time_of_day"]["log_loss"] < rows["persistence"]["log_loss"]
    accuracy = {m: a for m, (_, a) in scores.next_activity.items()}
    chosen = next(m for m in accuracy if m.startswith("chosen"))
    assert accuracy[chosen] > accuracy["time_of_day"] + 0.1 and accuracy[PER_HORIZON] >= accuracy[chosen]
    paths = write_activity_anticipation(tmp_path, [scores], "Test days of Clock: the activity ahead")
    assert [p.name for p in paths] == ["activity_anticipation.csv", "next_activity.csv", "activity_anticipation.png"]
    rows = list(csv.DictReader(paths[0].open()))
    assert len(rows) == 6 * 6 and {r["horizon_min"] for r in rows} == {str(10 * j) for j in range(1, 7)}
    assert paths[2].stat().st_size > 10_000


def test_the_time_of_day_is_mixed_in_as_far_as_training_days_say():
    """The weights are chosen per horizon on held-out training days (the model alone, w = 0, is a
    candidate): "nothing changes" on a clock home gets more of the hour the further ahead, and
    the mix then beats it on the test days."""
    home = clock_home(40, 6, 10, 7, 3.0)
    models = GlobeConfig().models.model_copy(update={"activity_estimator": "persistence"})
    weights = blend_weights([fold_scores(home, models, 10, 6, fold).losses for fold in data_folds(home, 4)])
    assert all(w in BLEND_WEIGHTS for w in weights)
    assert list(weights) == sorted(weights) and weights[0] < weights[-1]
    model = assembly.activity_model(models, 10).fit([d.activities for d in home.train])
    scores = score_anticipation(home.name, model, home.train, home.test, 6, 10, "model", weights)
    for minutes in (10, 60):
        rows = by_method(scores, minutes)
        assert rows["model + time of day"]["log_loss"] < min(rows["model"]["log_loss"], rows["time_of_day"]["log_loss"])


def _days(*rows: str) -> list[Day]:
    """Days of one letter per hour from 06:00 (each step its own hour)."""
    return [Day(f"d{i}", tuple(360 + 60 * t for t in range(len(r))), tuple(r), ((),) * len(r))
            for i, r in enumerate(rows)]


def _mode(dist: dict[str, float]) -> str:
    return max(sorted(dist), key=dist.__getitem__)


def test_hour_and_activity_counts_the_activity_h_ahead_and_backs_off_to_the_hour_then_staying():
    direct = HourActivityBaseline(2, shrinkage=0.01).fit(_days("AABBC", "AABCC", "AACCC"))
    assert _mode(direct.proba("A", 370, 1)) == "A"  # A at 06:xx: one step on A, A, A
    assert _mode(direct.proba("A", 370, 2)) == "B"  # two steps on: B, B, C
    assert abs(sum(direct.proba("A", 370, 2).values()) - 1) < 1e-9
    assert all(p > 0 for p in direct.proba("A", 370, 1).values())
    assert _mode(direct.proba("C", 360, 2)) == "B"  # C never at 06:xx: the hour's mode
    assert _mode(direct.proba("B", 23 * 60, 1)) == "B"  # an hour never seen: it stays
    assert _mode(direct.next_proba("A", 360)) == "B" and direct.next_proba("A", 360)["A"] == 0


def test_where_nothing_beats_staying_the_per_horizon_choice_stays_and_scores_as_persistence():
    """A home without routine: the decision chosen on training days is never far behind the best
    baseline on the test days, at any horizon, and one step ahead it is persistence's."""
    home = random_home(40, 8, seed=5)
    [scores] = run_activity_anticipation(GlobeConfig(), [home], Memo())
    for minutes in range(10, 70, 10):
        rows = by_method(scores, minutes)
        best = max(rows[m]["weighted_f1"] for m in ("persistence", "time_of_day", HOUR_ACTIVITY))
        assert rows[PER_HORIZON]["weighted_f1"] >= best - 0.02, (minutes, rows)
    one = by_method(scores, 10)
    assert one[PER_HORIZON]["weighted_f1"] >= one["persistence"]["weighted_f1"] - 0.002
