"""Activity anticipation scored for any home: the model beside persistence and the time-of-day
mode, persistence scored by hand, and the files a results folder gets."""

import csv

from globe import assembly
from globe.config import GlobeConfig
from globe.evaluation.activity_anticipation import (
    BLEND_WEIGHTS,
    blend_weights,
    fold_losses,
    run_activity_anticipation,
    score_anticipation,
    write_activity_anticipation,
)
from globe.evaluation.selection import Memo
from globe.evaluation.tuning import data_folds
from globe.models.baselines import PersistenceModel
from tests.simulated import clock_home


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
    assert max(accuracy, key=accuracy.get).startswith("chosen")
    paths = write_activity_anticipation(tmp_path, [scores], "Test days of Clock: the activity ahead")
    assert [p.name for p in paths] == ["activity_anticipation.csv", "next_activity.csv", "activity_anticipation.png"]
    rows = list(csv.DictReader(paths[0].open()))
    assert len(rows) == 4 * 6 and {r["horizon_min"] for r in rows} == {str(10 * j) for j in range(1, 7)}
    assert paths[2].stat().st_size > 10_000


def test_the_time_of_day_is_mixed_in_as_far_as_training_days_say():
    """The weights are chosen per horizon on held-out training days (the model alone, w = 0, is a
    candidate): "nothing changes" on a clock home gets more of the hour the further ahead, and
    the mix then beats it on the test days."""
    home = clock_home(40, 6, 10, 7, 3.0)
    models = GlobeConfig().models.model_copy(update={"activity_estimator": "persistence"})
    weights = blend_weights([fold_losses(home, models, 10, 6, fold) for fold in data_folds(home, 4)])
    assert all(w in BLEND_WEIGHTS for w in weights)
    assert list(weights) == sorted(weights) and weights[0] < weights[-1]
    model = assembly.activity_model(models, 10).fit([d.activities for d in home.train])
    scores = score_anticipation(home.name, model, home.train, home.test, 6, 10, "model", weights)
    for minutes in (10, 60):
        rows = by_method(scores, minutes)
        assert rows["model + time of day"]["log_loss"] < min(rows["model"]["log_loss"], rows["time_of_day"]["log_loss"])
