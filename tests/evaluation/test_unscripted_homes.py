"""Model choice on homes that are not scripted: a proper scoring rule on training days picks a
model no worse than "nothing changes" and the time-of-day mode where there is no routine, and a
model that knows the clock where the routine is a clock (tests/simulated.py writes both homes)."""

from collections import Counter

import pytest

from globe import assembly
from globe.config import GlobeConfig
from globe.evaluation.experiments import run_methods
from globe.evaluation.metrics import f1, log_loss
from globe.evaluation.selection import Memo
from globe.evaluation.tuning import tuned_models
from tests.simulated import clock_home, random_home


def scores(household, predict) -> dict[str, float]:
    """Log loss and weighted F1 of the next activity at steps 1.. of the test days."""
    true, pred, p_true = [], [], []
    for day in household.test:
        for t in range(1, len(day)):
            dist = predict(day.activities, t)
            true.append(day.activities[t])
            pred.append(max(sorted(dist), key=dist.get))
            p_true.append(dist.get(day.activities[t], 0.0))
    return {"log_loss": log_loss(p_true), "f1": f1(true, pred)}


def compared(household) -> tuple[str, dict[str, dict[str, float]]]:
    cfg = GlobeConfig()
    models, _ = tuned_models(household, cfg, "routine", Memo())
    chosen = assembly.activity_model(models, assembly.step_minutes(household, cfg))
    chosen.fit([d.activities for d in household.train])
    at_step = [Counter(d.activities[t] for d in household.train) for t in range(len(household.train[0]))]
    mode = {t: {a: n / sum(c.values()) for a, n in c.items()} for t, c in enumerate(at_step)}
    return models.activity_estimator, {
        "chosen": scores(household, lambda day, t: chosen.predict_proba(day[:t])),
        "persistence": scores(household, lambda day, t: {day[t - 1]: 1.0}),
        "time_of_day": scores(household, lambda day, t: mode[t]),
    }


@pytest.mark.parametrize("seed", [1, 2])
def test_a_home_with_no_routine_gets_a_model_no_worse_than_the_baselines(seed):
    _, s = compared(random_home(75, 10, 10, seed))
    assert s["chosen"]["log_loss"] < s["persistence"]["log_loss"] / 2
    assert s["chosen"]["log_loss"] < s["time_of_day"]["log_loss"]
    assert s["chosen"]["f1"] >= s["persistence"]["f1"] - 0.01
    assert s["chosen"]["f1"] > s["time_of_day"]["f1"]


@pytest.mark.parametrize("seed", [1, 2])
def test_a_home_whose_routine_is_a_clock_gets_a_model_that_wins_clearly(seed):
    estimator, s = compared(clock_home(75, 10, 10, seed, 3.0))
    assert estimator in ("clock", "routine")
    assert s["chosen"]["log_loss"] < 0.5 * s["persistence"]["log_loss"]
    assert s["chosen"]["log_loss"] < 0.8 * s["time_of_day"]["log_loss"]
    assert s["chosen"]["f1"] > s["time_of_day"]["f1"] + 0.05


def test_the_alignment_cross_validation_chooses_is_the_best_on_test_days():
    """Which activity a use is credited to is searched with the routine models, through the
    protocol (so the credited activity must itself be predicted): on the clock home the choice is
    the alignment whose objects are then predicted best on the test days; with one candidate
    there is no search."""
    home = clock_home(45, 8, 10, 5)
    chosen = run_methods(GlobeConfig(), [home], ["routine"], None, Memo())[0]
    search = chosen.selection["alignment"]
    assert [c["alignment"] for c, _ in search.scores] == ["previous", "current", "hybrid"]
    test_f1 = {}
    for alignment in ("previous", "current", "hybrid"):
        cfg = GlobeConfig().with_overrides({"sequences.alignment": alignment, "selection.alignments": [alignment]})
        run = run_methods(cfg, [home], ["routine"], None, Memo())[0]
        assert "alignment" not in run.selection
        test_f1[alignment] = f1([r.true for r in run.evaluation.objects], [r.predicted for r in run.evaluation.objects])
    assert test_f1[search.best["alignment"]] >= max(test_f1.values()) - 0.01
    assert max(test_f1.values()) - min(test_f1.values()) > 0.03  # the choice matters here
