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
from globe.session.build import activity_model_summary
from tests.simulated import clock_home, hourly_home, random_home


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


@pytest.mark.parametrize("seed", [0, 1])
def test_a_home_whose_activity_follows_the_hour_alone_deploys_the_time_of_day(seed):
    """Every step draws its activity afresh from the hour's: the time of day alone (the clock
    model pooled over the current activity) is chosen on the training days, and on the test days
    it predicts better than the clock model that also reads the current activity, than
    persistence and than the per-step time-of-day mode it generalises."""
    home = hourly_home(seed=seed)
    cfg = GlobeConfig()
    models, selections = tuned_models(home, cfg, "routine", Memo())
    assert (models.activity_estimator, models.clock_by_activity) == ("clock", False)
    assert models.clock_slot_minutes in (30, 60)  # the hour's pattern, not a step's few counts
    step = assembly.step_minutes(home, cfg)
    chosen = assembly.activity_model(models, step).fit([d.activities for d in home.train])
    reading = assembly.activity_model(models.model_copy(update={"clock_by_activity": True}), step)
    reading.fit([d.activities for d in home.train])
    test = scores(home, lambda day, t: chosen.predict_proba(day[:t]))
    assert test["log_loss"] < scores(home, lambda day, t: reading.predict_proba(day[:t]))["log_loss"]
    _, s = compared(home)
    assert s["chosen"]["log_loss"] < s["time_of_day"]["log_loss"] and s["chosen"]["f1"] > s["persistence"]["f1"] + 0.1
    assert "time of day alone" in activity_model_summary(models)


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


def test_where_days_carry_dates_the_day_of_the_week_is_offered_and_chosen_when_it_tells_days_apart():
    """Day types are tried only where dated training days span two weeks; on a home whose
    weekends differ from its weekdays in a way the last activity and the time cannot tell (what
    follows breakfast), cross-validation chooses them and the test days' log loss of what follows
    breakfast drops well below the same home's without dates; on the clock home (whose weekends
    the last activity mostly reveals) the choice is no worse than without dates."""
    from globe.evaluation.tuning import day_types_tried
    from tests.simulated import weekly_home

    sel = GlobeConfig().selection
    assert day_types_tried(weekly_home(20, 5, 0, dated=False), sel) == ["none"]
    assert day_types_tried(weekly_home(15, 2, 0), sel) == ["none"]  # thirteen dated training days: under two weeks
    assert day_types_tried(weekly_home(20, 5, 0), sel) == ["none", "weekend", "weekday"]

    def chosen(home) -> tuple[str, float, float]:
        """The day types chosen, the log loss on the test days and that of what follows breakfast."""
        models, _ = tuned_models(home, GlobeConfig(), "routine", Memo())
        model = assembly.fitted_activity_model(models, 10, home.train)
        steps = [(d.activities[t - 1], d.activities[t], dist.get(d.activities[t], 0.0)) for d in home.test
                 for t, dist in enumerate(model.scan_proba(d.activities, d.weekday)) if t]
        types = models.clock_day_types if models.activity_estimator == "clock" else "none"
        return types, log_loss([p for *_, p in steps]), log_loss([p for a, b, p in steps if a == "breakfast" != b])

    dated, undated = chosen(weekly_home(56, 14, 3)), chosen(weekly_home(56, 14, 3, dated=False))
    assert dated[0] in ("weekend", "weekday") and undated[0] == "none"
    assert dated[2] < 0.75 * undated[2]
    assert dated[1] < undated[1]
    assert chosen(clock_home(75, 10, 10, 1, 3.0, dated=True))[1] <= chosen(clock_home(75, 10, 10, 1, 3.0))[1] + 0.01


def test_most_is_searched_only_where_the_days_say_what_covers_each_step():
    """Days written with a covering column (as imported days are) add 'most' to the alignments
    cross-validation tries, and its choice is again the best on the test days."""
    home = clock_home(45, 8, 10, 5, covering=True)
    chosen = run_methods(GlobeConfig(), [home], ["routine"], None, Memo())[0]
    search = chosen.selection["alignment"]
    assert [c["alignment"] for c, _ in search.scores] == ["previous", "current", "hybrid", "most"]
    test_f1 = {}
    for alignment in ("previous", "current", "hybrid", "most"):
        cfg = GlobeConfig().with_overrides({"sequences.alignment": alignment, "selection.alignments": [alignment]})
        run = run_methods(cfg, [home], ["routine"], None, Memo())[0]
        test_f1[alignment] = f1([r.true for r in run.evaluation.objects], [r.predicted for r in run.evaluation.objects])
    assert test_f1[search.best["alignment"]] >= max(test_f1.values()) - 0.01
    assert test_f1["most"] != test_f1["current"]  # the covering labels changed what was credited


@pytest.mark.parametrize("seed", [1, 2])
def test_the_next_activity_said_is_chosen_on_f1_and_is_not_behind_staying(seed):
    """The probabilities are chosen by log loss; what is *said* is chosen apart, on the F1 it is
    scored by: on a home with no routine the activity said at the next step is, on the test days,
    within 0.002 of "it stays the same" (the issue's bar), whatever the model's argmax does."""
    from globe.models.base import stay_or_change

    home = random_home(75, 10, 10, seed)
    cfg = GlobeConfig()
    models, selections = tuned_models(home, cfg, "routine", Memo())
    assert "decision" in selections and models.stay_margin in cfg.selection.stay_margins
    chosen = assembly.activity_model(models, 10).fit([d.activities for d in home.train])
    true, said, stay = [], [], []
    for day in home.test:
        for t, dist in enumerate(chosen.scan_proba(day.activities)):
            if t:
                true.append(day.activities[t])
                said.append(stay_or_change(chosen.top(dist), dist, day.activities[t - 1], models.stay_margin))
                stay.append(day.activities[t - 1])
    assert f1(true, said) >= f1(true, stay) - 0.002
