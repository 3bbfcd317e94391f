"""Cross-validation on training days: folds, selection, and that simpler models can win."""

import math
import random
from dataclasses import replace

from globe.config import GlobeConfig
from globe.data.records import Day
from globe.evaluation.metrics import LOG_LOSS_FLOOR
from globe.evaluation.selection import Memo
from globe.evaluation.tuning import ScanMemo, activity_scores, tuned_gate, tuned_models
from globe.models.baselines import PersistenceModel
from globe.reasoning.backends.base import Choice, LLMBackend


def _patternless(household, seed: int):
    """Days of long runs whose next activity is random: nothing beats "the activity stays"."""
    rng = random.Random(seed)
    acts = sorted({a for d in household.train for a in d.activities})
    days = []
    for i, template in enumerate(household.train[:20]):
        seq: list[str] = []
        while len(seq) < len(template):
            seq += [rng.choice(acts)] * rng.randint(6, 14)
        days.append(replace(template, name=f"train/{i:03d}", activities=tuple(seq[: len(template)])))
    return replace(household, train=tuple(days), test=())


def test_on_runs_of_random_activities_f1_picks_persistence_and_log_loss_a_model_of_durations(households, seed):
    """By F1 nothing beats "the activity stays"; by log loss (the default) persistence pays for
    every change it calls impossible, and a model of how long runs last wins."""
    h = _patternless(households["C"], seed)
    by_f1 = GlobeConfig().with_overrides({"selection.criterion": "f1"})
    models, selection = tuned_models(h, by_f1, "routine", Memo())
    assert models.activity_estimator == "persistence", selection["activity"].scores[:3]
    assert {p["activity_estimator"] for p, _ in selection["activity"].scores} == {"persistence", "longest", "routine",
                                                                                 "clock"}
    models, selection = tuned_models(h, GlobeConfig(), "routine", Memo())
    losses = {p["activity_estimator"]: m["log_loss"] for (p, _), m in
              zip(selection["activity"].scores, selection["activity"].metrics)}
    assert models.activity_estimator != "persistence"
    assert min(losses.values()) < 0.75 * losses["persistence"]


def test_cv_keeps_the_routine_model_on_a_real_routine(households):
    h = replace(households["B"], train=households["B"].train[:30])
    models, selection = tuned_models(h, GlobeConfig(), "routine", Memo())
    assert models.activity_estimator == "routine"
    best = max(s for _, s in selection["activity"].scores)
    persistence = next(s for p, s in selection["activity"].scores if p["activity_estimator"] == "persistence")
    assert best > persistence


class EchoNgram(LLMBackend):
    """Answers the first listed candidate in the gate's own ranking order (the n-gram's choice)."""

    name = "echo"

    def choose(self, context, candidates):
        return Choice(candidates[0], {c: -float(i) for i, c in enumerate(candidates)})


def test_gate_cv_prefers_never_asking_when_the_llm_adds_nothing(households):
    h = replace(households["C"], train=households["C"].train[:15])
    cfg = GlobeConfig()
    memo = Memo()
    models, _ = tuned_models(h, cfg, "routine", memo)
    gate, selection = tuned_gate(h, cfg, models, EchoNgram(), memo, examples=2)
    scores = [s for _, s in selection.scores]
    assert max(scores) == scores[0]  # asking only repeats the n-gram: no candidate beats never asking
    assert gate.threshold == 0.0 and gate.examples == 2
    assert len(selection.scores) == 1 + len(cfg.selection.gate_thresholds) * (1 + len(cfg.selection.combine_weights))


def test_candidates_sharing_one_fit_per_fold_score_as_if_each_were_fitted_alone(households):
    """Candidates that count the same share one fit per fold (prediction parameters aside): their
    scores are those of models fitted one by one."""
    from globe import assembly
    from globe.evaluation.selection import FitKey, grid
    from globe.evaluation.tuning import activity_scores, data_folds, fitted_activity, fold_days

    h = replace(households["A"], train=households["A"].train[:24])
    cfg = GlobeConfig().models
    space = [{"activity_estimator": "longest"}] + grid({"activity_estimator": ["witten_bell", "routine"],
                                                        "routine_order": [2, 4], "time_weight": [0.0, 2.0],
                                                        "routine_time_weight": [0.0, 1.0]})
    memo = Memo()
    for params in space:
        models = cfg.model_copy(update=params)
        for fold in data_folds(h, 3):
            train, held_out = fold_days(h, fold)
            shared = activity_scores(fitted_activity(h, fold, models, memo, 10), held_out)
            alone = assembly.fitted_activity_model(models, 10, train)
            assert shared == activity_scores(alone, held_out)  # type: ignore[arg-type]
    counted = [k for k in memo.entries(lambda k: isinstance(k, FitKey) and not k.model.endswith(":predicting")
                                       and k.model != "sequences")]
    assert len(counted) == 2 * 3  # per fold, one n-gram fit (longest and witten_bell share it) and one routine fit


def test_a_perfect_prediction_scores_a_log_loss_of_zero_and_an_empty_fold_the_floor():
    model = ScanMemo(PersistenceModel().fit([("a", "a", "a")]))
    day = Day("train/2024-01-01", (360, 370, 380), ("a", "a", "a"), ((), (), ()))
    assert activity_scores(model, [day])["log_loss"] == 0.0
    assert activity_scores(model, [])["log_loss"] == -math.log(LOG_LOSS_FLOOR)
