"""How well activities are recognised from a home's sensors, as the literature reports it, and what
that costs GLOBE's predictions.

- **Scores** (:func:`recognition_scores`): time-slice accuracy (the share of steps right) and class
  accuracy (the mean over activities of the share of each one's steps right), as van Kasteren et
  al. report them: time-slice accuracy alone is flattered by the longest activity. Per-class F1
  and the confusion matrix beside them.
- **Choice on training days** (:func:`choose_settings`): the feature set, the emission's weight
  and self-training, by class accuracy of online recognition on held-out blocks of the labelled
  training days (:func:`~globe.evaluation.selection.folds`); the default unless a candidate
  wins beyond noise (:func:`~globe.evaluation.selection.best_beyond_noise`). Test days are
  never looked at.
- **Learning curve** (:func:`learning_curve`): trained on the last k labelled training days (the
  ones a person most recently labelled), the other training days unlabelled, scored on the test days.
- **Asking curve** (:func:`asking_curve`): from k labelled days (settings chosen on them), the
  other training days are lived through once, online, with a budget of questions a day answered
  from the annotation, and learnt from at each day's end; scored on the test days, beside the
  same budget spent at random times (the mean of three draws). The worth rule is fixed
  (:mod:`globe.recognition.asking`), so nothing about asking is chosen, on test days or others.
- **End to end** (:func:`end_to_end`): GLOBE's activity model fed recognised (online) activities
  instead of the annotated ones: one-step weighted F1 and next-different-activity accuracy, both
  against the annotation.
- **Rows from libraries** (:func:`library_rows`): a linear-chain CRF (sklearn-crfsuite) over the
  same features and the hour, and a plain HMM (hmmlearn) over the feature set chosen on held-out
  training days, each when installed (``pip install globe[recognition]``); offered to
  cross-validation beside GLOBE's recogniser to label the days nobody labelled (:func:`choose_labeller`).
"""

from __future__ import annotations

import csv
import json
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Callable, Literal, Mapping, Sequence

import numpy as np

from globe.data.records import Day, Household
from globe.data.sensors import SensorData
from globe.evaluation.metrics import f1
from globe.evaluation.selection import best_beyond_noise, folds
from globe.models.base import ActivityModelBase
from globe.recognition import hybrid, library
from globe.recognition.asking import DayAsker, QuestionPolicy, random_steps, worth
from globe.recognition.features import REPRESENTATIONS
from globe.recognition.labelling import Labeller
from globe.recognition.library import CRF, HMM, CrfRecogniser, PlainHmmRecogniser
from globe.recognition.recogniser import Recogniser, RecognitionSettings

LEARNING_DAYS = (1, 3, 7, 14, None)
"""Labelled training days of the learning curve (None: all)."""
BUDGETS = (0, 1, 2, 5)
"""Questions a day of the asking curve."""
WEIGHTS = (1.0, 0.5, 0.3)
EDGE_STRENGTHS = (2.0, 10.0, 50.0)
"""How strongly the evidence on changes is shrunk to each activity's own (pseudo-steps) in the
candidates cross-validation offers: few changes of a kind say little, many say much."""
CV_FOLDS = 4


@dataclass(frozen=True, slots=True)
class Scores:
    """Recognition against the annotation over some steps."""

    time_slice: float
    class_accuracy: float
    f1: dict[str, float]
    labels: tuple[str, ...]
    confusion: np.ndarray  # (true x predicted) step counts over ``labels``

    def row(self) -> dict[str, float]:
        return {"time_slice_accuracy": round(self.time_slice, 4), "class_accuracy": round(self.class_accuracy, 4)}


def recognition_scores(true: Sequence[str], predicted: Sequence[str]) -> Scores:
    """Time-slice and class accuracy, per-class F1 and the confusion matrix (see module doc)."""
    if len(true) != len(predicted):
        raise ValueError(f"{len(true)} true and {len(predicted)} predicted steps")
    if not true:
        raise ValueError("no step to score")
    labels = tuple(sorted(set(true) | set(predicted)))
    index = {a: i for i, a in enumerate(labels)}
    confusion = np.zeros((len(labels), len(labels)), dtype=np.int64)
    np.add.at(confusion, ([index[a] for a in true], [index[a] for a in predicted]), 1)
    right = np.diag(confusion)
    support = confusion.sum(axis=1)
    seen = support > 0
    per_class = {}
    for i, label in enumerate(labels):
        guessed = confusion[:, i].sum()
        precision = right[i] / guessed if guessed else 0.0
        recall = right[i] / support[i] if support[i] else 0.0
        if support[i]:
            per_class[label] = 0.0 if precision + recall == 0 else float(2 * precision * recall / (precision + recall))
    return Scores(float(right.sum() / confusion.sum()), float((right[seen] / support[seen]).mean()), per_class, labels,
                  confusion)


def _flat(days: Sequence[Day]) -> list[str]:
    return [a for d in days for a in d.activities]


def _score(recogniser: Recogniser, days: Sequence[Day], smooth: bool = False) -> Scores:
    predicted = recogniser.predict(days, smooth=smooth)
    return recognition_scores(_flat(days), [a for p in predicted for a in p])


def candidates() -> list[RecognitionSettings]:
    """The representations and weights of naive Bayes cross-validation chooses among first, the
    default first (the emission and self-training are decided after them, for the one chosen)."""
    out = [RecognitionSettings()]
    for features in REPRESENTATIONS:
        for weight in WEIGHTS:
            s = RecognitionSettings(features=features, weight=weight)
            if s not in out:
                out.append(s)
    return out


Reading = Literal["online", "hindsight"]


def choose_settings(labelled: Sequence[Day], sensors: SensorData, step_minutes: int,
                    unlabelled: Sequence[Day] = (), options: Sequence[RecognitionSettings] | None = None,
                    reading: Reading = "online") -> RecognitionSettings:
    """The recogniser's settings by class accuracy on held-out blocks of ``labelled`` days (see
    module doc), read as they will be used: ``online`` (the service, step by step) or with
    ``hindsight`` (labelling past days: the most probable sequence). The representation and
    weight first (among ``options``, default :func:`candidates`: the default unless others win
    beyond noise, then the best of those); for the default search and where scikit-learn is
    installed, the discriminative emission over the representation and at the weight chosen
    (:class:`~globe.recognition.hybrid.DiscriminativeEmission`) then joins them, by the same rule
    (one candidate, not one per representation: each costs a classifier per fold). It takes naive
    Bayes's weight because the weight tempers more than sensors firing together: at short steps
    the same reading repeats over many steps, evidence neither emission counts once (measured,
    1-minute steps, 7 labelled days: untempered, test-day time-slice accuracy 0.784; at naive
    Bayes's weight 0.898); then the one chosen reading each step's features also as evidence on
    the change after it (``edges``: :class:`~globe.recognition.edges.SensorEdges`, at each
    strength of :data:`EDGE_STRENGTHS`), where it beats the one chosen itself beyond noise;
    then whether self-training on the ``unlabelled`` days beats the one chosen beyond noise. With
    fewer than two labelled days, nothing to hold out: the first option, the default."""
    return _searched(labelled, sensors, step_minutes, unlabelled, options, reading)[0]


def _held_out(labelled: Sequence[Day], fit: Callable[[Sequence[Day]], Any],
              score: Callable[[Any, Sequence[Day]], Scores]) -> list[float]:
    """Per block of held-out ``labelled`` days (:func:`~globe.evaluation.selection.folds`, at most
    :data:`CV_FOLDS`), the class accuracy ``score`` gives a recogniser ``fit`` on the other days."""
    scores = []
    for train, held in folds(len(labelled), min(CV_FOLDS, len(labelled))):
        scores.append(score(fit([labelled[i] for i in train]), [labelled[i] for i in held]).class_accuracy)
    return scores


def _searched(labelled: Sequence[Day], sensors: SensorData, step_minutes: int, unlabelled: Sequence[Day],
              options: Sequence[RecognitionSettings] | None, reading: Reading
              ) -> tuple[RecognitionSettings, list[float]]:
    """:func:`choose_settings`' choice and its held-out scores, fold by fold (none with fewer than
    two labelled days)."""
    default_search = options is None
    options = list(options or candidates())
    if len(labelled) < 2:
        return options[0], []

    def per_fold(settings: RecognitionSettings) -> list[float]:
        return _held_out(labelled, lambda days: Recogniser(settings).fit(days, sensors, step_minutes, unlabelled),
                         lambda fitted, days: _score(fitted, days, smooth=reading == "hindsight"))
    first = [(settings, per_fold(settings)) for settings in options]
    chosen = best_beyond_noise(first)
    if default_search and chosen.emission == "naive_bayes" and hybrid.available():
        other = replace(chosen, emission="discriminative")  # at naive Bayes's weight (see the doc)
        first.append((other, per_fold(other)))
        chosen = best_beyond_noise(first)  # by the same rule: against the default, the best mean beyond noise
    if default_search and not chosen.edges:  # a refinement of the one chosen: it must beat that one
        edged = [(e, per_fold(e)) for e in (replace(chosen, edges=True, edge_strength=strength)
                                            for strength in EDGE_STRENGTHS)]
        first += edged
        chosen = best_beyond_noise([next(f for f in first if f[0] == chosen), *edged])
    kept = next(f for f in first if f[0] == chosen)
    if not unlabelled or chosen.self_training:
        return kept
    trained = replace(chosen, self_training=True)
    last = [kept, (trained, per_fold(trained))]
    chosen = best_beyond_noise(last)
    return next(f for f in last if f[0] == chosen)


def deployed_settings(household: Household, sensors: SensorData, step_minutes: int,
                      options: Sequence[RecognitionSettings] | None = None) -> RecognitionSettings:
    """The recogniser's settings a household with sensors is deployed with (``POST /households``,
    ``globe evaluate --activities recognised``): :func:`choose_settings` on its labelled training
    days that have recorded sensors (the first option, the default, with fewer than two)."""
    return choose_settings(sensors.recorded(household.train), sensors, step_minutes, options=options)


def fit_recogniser(labelled: Sequence[Day], sensors: SensorData, step_minutes: int, unlabelled: Sequence[Day] = (),
                   options: Sequence[RecognitionSettings] | None = None, reading: Reading = "online") -> Recogniser:
    """A home's recogniser with the settings chosen on its labelled days for ``reading``."""
    settings = choose_settings(labelled, sensors, step_minutes, unlabelled, options, reading)
    return Recogniser(settings).fit(labelled, sensors, step_minutes, unlabelled)


def learning_curve(household: Household, sensors: SensorData, step_minutes: int,
                   counts: Sequence[int | None] = LEARNING_DAYS,
                   options: Sequence[RecognitionSettings] | None = None,
                   fitted: Recogniser | None = None) -> list[dict[str, Any]]:
    """One row per number of labelled days (see module doc): online and smoothed accuracies
    (``fitted``: the recogniser of every training day, when the caller has it already)."""
    rows = []
    train = list(household.train)
    for k in counts:
        n = len(train) if k is None else min(k, len(train))
        if k is not None and k > len(train):
            continue
        labelled, unlabelled = train[len(train) - n:], train[: len(train) - n]
        recogniser = (fitted if fitted is not None and n == len(train)
                      else fit_recogniser(labelled, sensors, step_minutes, unlabelled, options))
        online, hindsight = _score(recogniser, household.test), _score(recogniser, household.test, smooth=True)
        rows.append({"labelled_days": n, **online.row(),
                     "smoothed_time_slice_accuracy": round(hindsight.time_slice, 4),
                     "smoothed_class_accuracy": round(hindsight.class_accuracy, 4),
                     "settings": recogniser.describe()})
    return rows


ASKING = ("worth", "random")
"""How the asking curve spends its budget: ``worth`` (:func:`~globe.recognition.asking.worth` with
the labelled counts), ``unsure`` (the chance of being wrong alone) and ``random`` (random times)."""
DRAWS = 3
"""Random draws of asking at random times, averaged, so the comparison is not one draw."""


def live_asking(settings: RecognitionSettings, labelled: Sequence[Day], unlabelled: Sequence[Day],
                sensors: SensorData, step_minutes: int, budget: int, how: str = "worth",
                seed: int = 0) -> tuple[Recogniser, list[list[str | None]]]:
    """Live through the ``unlabelled`` days in order, online, asking ``budget`` questions a day
    (``how``: see :data:`ASKING`; ``seed`` draws the random times) answered from their annotation,
    and learn each day at its end. Returns the recogniser after the last day and the answers."""
    if how not in ("worth", "unsure", "random"):
        raise ValueError(f"unknown way of asking {how!r}; expected worth, unsure or random")
    recogniser = Recogniser(settings).fit(labelled, sensors, step_minutes)
    answered: list[list[str | None]] = []
    for i, day in enumerate(unlabelled):
        ask: Callable[[int, np.ndarray], bool]
        if how == "random":
            ask = _at_steps(frozenset(random_steps(len(day), budget, (seed, i, budget))))
        else:  # paced by the worths of the days seen, read by today's recogniser (yesterday's was less sure)
            counts = recogniser.labelled_counts() if how == "worth" else None
            seen = recogniser.filter([*labelled, *unlabelled[:i]])
            ask = DayAsker(QuestionPolicy(budget, np.concatenate([worth(p, counts) for p in seen])), len(day),
                           labelled=counts)
        said = recogniser.filter_asking(day, ask, day.activities.__getitem__)[1]
        answered.append(said)
        recogniser = Recogniser(settings).fit(labelled, sensors, step_minutes, unlabelled[: i + 1], answered)
    return recogniser, answered


def _at_steps(steps: frozenset[int]) -> Callable[[int, np.ndarray], bool]:
    return lambda step, _posterior: step in steps


def asking_curve(household: Household, sensors: SensorData, step_minutes: int, labelled_days: int = 3,
                 budgets: Sequence[int] = BUDGETS, seed: int = 0,
                 options: Sequence[RecognitionSettings] | None = None, asking: Sequence[str] = ASKING,
                 draws: int = DRAWS) -> list[dict[str, Any]]:
    """Per budget of questions a day: class and time-slice accuracy on the test days after living
    through the unlabelled training days (:func:`live_asking`) each way in ``asking`` (random
    times: the mean of ``draws`` draws, and their spread), with the questions asked (see module doc)."""
    train = list(household.train)
    labelled, unlabelled = train[len(train) - labelled_days:], train[: len(train) - labelled_days]
    settings = replace(choose_settings(labelled, sensors, step_minutes, options=options), self_training=False)
    rows = []
    for budget in budgets:
        row: dict[str, Any] = {"labelled_days": len(labelled), "questions_per_day": budget}
        silent: tuple[Scores, int] | None = None
        for how in asking:
            results = []
            for r in range(draws if how == "random" and budget else 1):
                if budget == 0 and silent is not None:  # no question: every way is the same
                    results.append(silent)
                    continue
                recogniser, said = live_asking(settings, labelled, unlabelled, sensors, step_minutes, budget, how,
                                               seed + r)
                results.append((_score(recogniser, household.test), sum(a is not None for s in said for a in s)))
                silent = results[-1] if budget == 0 else None
            classes = [sc.class_accuracy for sc, _ in results]
            row[f"{how}_class_accuracy"] = round(float(np.mean(classes)), 4)
            row[f"{how}_time_slice_accuracy"] = round(float(np.mean([sc.time_slice for sc, _ in results])), 4)
            row[f"{how}_questions"] = round(float(np.mean([n for _, n in results])), 1)
            if len(results) > 1:
                row[f"{how}_class_accuracy_sd"] = round(float(np.std(classes)), 4)
        rows.append(row)
    return rows


def end_to_end(model: ActivityModelBase, days: Sequence[Day], recognised: Sequence[Sequence[str]],
               expected: Sequence[np.ndarray] | None = None, labels: Sequence[str] = ()) -> dict[str, Any]:
    """``model`` (fitted on training days) predicting each next activity of ``days`` from their
    annotated and from their ``recognised`` histories, both scored against the annotation:
    one-step weighted F1 and next-different-activity accuracy (at each change of the annotated
    activity, the most probable activity other than the current one against the next one). With
    ``expected`` (per day, steps x ``labels``: P(a_{t+1} | sensors up to t), the recogniser's
    :meth:`~globe.recognition.recogniser.Recogniser.predictive` over the same model) also the
    filter's own prediction, which weighs every history the sensors allow (``filtered_...``)."""
    out: dict[str, Any] = {}
    for name, histories in (("annotated", [d.activities for d in days]), ("recognised", recognised)):
        true, predicted, hits, events = [], [], 0, 0
        for day, history in zip(days, histories):
            acts = day.activities
            for t in range(1, len(acts)):
                dist = model.predict_proba(tuple(history[:t]), day.weekday)
                best = model.top(dist)
                true.append(acts[t])
                predicted.append(best if best is not None else history[t - 1])
                if acts[t] != acts[t - 1]:
                    other = {a: p for a, p in dist.items() if a != history[t - 1]}
                    events += 1
                    hits += int((model.top(other) if other else None) == acts[t])
        out[f"{name}_one_step_f1"] = round(f1(true, predicted) or 0.0, 4)
        out[f"{name}_next_different_accuracy"] = round(hits / events, 4) if events else None
    if expected is not None:
        names = list(labels)
        true, predicted, hits, events = [], [], 0, 0
        for day, history, rows in zip(days, recognised, expected):
            acts = day.activities
            for t in range(1, len(acts)):
                row = rows[t - 1]
                true.append(acts[t])
                predicted.append(names[int(row.argmax())])
                if acts[t] != acts[t - 1]:
                    masked = row.copy()
                    if history[t - 1] in names:
                        masked[names.index(history[t - 1])] = -1.0
                    events += 1
                    hits += int(names[int(masked.argmax())] == acts[t])
        out["filtered_one_step_f1"] = round(f1(true, predicted) or 0.0, 4)
        out["filtered_next_different_accuracy"] = round(hits / events, 4) if events else None
    return out


def crf_scores(household: Household, sensors: SensorData, step_minutes: int, labelled: Sequence[Day] | None = None
               ) -> Scores | None:
    """The linear-chain CRF (:class:`~globe.recognition.library.CrfRecogniser`) trained on
    ``labelled`` (default: every training day), scored on the test days read with hindsight; None
    when sklearn-crfsuite is not installed."""
    if CRF not in library.available():
        return None
    fitted = CrfRecogniser().fit(list(household.train if labelled is None else labelled), sensors, step_minutes)
    return _hindsight_scores(fitted, household.test)


def hmm_scores(household: Household, sensors: SensorData, step_minutes: int, labelled: Sequence[Day] | None = None,
               features: tuple[str, ...] | None = None) -> Scores | None:
    """The plain HMM (:class:`~globe.recognition.library.PlainHmmRecogniser`) counted on
    ``labelled`` (default: every training day) over ``features`` (default: chosen by
    :func:`choose_hmm_features`), scored on the test days read with hindsight; None when hmmlearn
    is not installed. Where GLOBE's recogniser differs: its dynamics know the clock, and it also
    reads each step online."""
    if HMM not in library.available():
        return None
    labelled = list(household.train if labelled is None else labelled)
    features = features or choose_hmm_features(labelled, sensors, step_minutes)
    return _hindsight_scores(PlainHmmRecogniser(features).fit(labelled, sensors, step_minutes), household.test)


def _hindsight_scores(fitted: Labeller, days: Sequence[Day]) -> Scores:
    return recognition_scores(_flat(days), [a for p in hindsight(fitted, days) for a in p])


def hindsight(fitted: Labeller, days: Sequence[Day]) -> list[list[str]]:
    """Each day's most probable sequence as ``fitted`` reads it with hindsight (its :meth:`decode`)."""
    return [[fitted.labels[i] for i in path.argmax(axis=1).tolist()] for path in fitted.decode(days)]


def choose_hmm_features(labelled: Sequence[Day], sensors: SensorData, step_minutes: int) -> tuple[str, ...]:
    """The plain HMM's feature set among :data:`~globe.recognition.features.REPRESENTATIONS`, by
    class accuracy on held-out blocks of ``labelled`` (the first, with fewer than two days)."""
    if len(labelled) < 2:
        return REPRESENTATIONS[0]
    return best_beyond_noise([(f, _held_out(labelled, lambda days, f=f: PlainHmmRecogniser(f).fit(  # type: ignore[misc]
        days, sensors, step_minutes), _hindsight_scores)) for f in REPRESENTATIONS])


@dataclass(frozen=True, slots=True)
class LabellerChoice:
    """The recogniser chosen to label unlabelled days, fitted on every labelled day, and each
    candidate's mean class accuracy on the held-out labelled days (read with hindsight)."""

    labeller: Labeller
    name: str
    held_out: dict[str, float]

    def describe(self) -> dict[str, Any]:
        return {"chosen": self.name, **self.labeller.describe(),
                "held_out_class_accuracy": {k: round(v, 4) for k, v in self.held_out.items()}}


GLOBE_LABELLER = "globe (clock dynamics, sensor emission)"


def choose_labeller(labelled: Sequence[Day], sensors: SensorData, step_minutes: int, unlabelled: Sequence[Day] = (),
                    options: Sequence[RecognitionSettings] | None = None) -> LabellerChoice:
    """Which recogniser labels the ``unlabelled`` days with hindsight: GLOBE's
    (:func:`choose_settings` on ``labelled``, read with hindsight) unless a library recogniser
    (:mod:`globe.recognition.library`, those installed; the HMM's features chosen on ``labelled``)
    reads held-out blocks of ``labelled`` days better, beyond noise, by class accuracy. Each is
    configured on every labelled day and scored fold by fold; the winner is fitted on them all.
    With fewer than two labelled days there is nothing to hold out: GLOBE's."""
    labelled = list(labelled)
    settings, held_out = _searched(labelled, sensors, step_minutes, unlabelled, options, "hindsight")
    ours = Recogniser(settings).fit(labelled, sensors, step_minutes, unlabelled)
    if len(labelled) < 2:
        return LabellerChoice(ours, GLOBE_LABELLER, {})
    makers: dict[str, Callable[[Sequence[Day]], Labeller]] = {}
    installed = library.available()
    if CRF in installed:
        makers[CRF] = lambda days: CrfRecogniser().fit(days, sensors, step_minutes)
    if HMM in installed:
        features = choose_hmm_features(labelled, sensors, step_minutes)
        makers[HMM] = lambda days: PlainHmmRecogniser(features).fit(days, sensors, step_minutes)
    # GLOBE's held-out scores are its settings search's own (the same folds, read the same way)
    scored = [(GLOBE_LABELLER, held_out)] + [(name, _held_out(labelled, make, _hindsight_scores))
                                             for name, make in makers.items()]
    name = best_beyond_noise(scored)
    held = {n: float(np.mean(s)) for n, s in scored}
    return LabellerChoice(ours if name == GLOBE_LABELLER else makers[name](labelled), name, held)


def library_rows(household: Household, sensors: SensorData, step_minutes: int) -> dict[str, Scores]:
    """The rows from well-kept libraries beside GLOBE's recogniser, trained on every training day
    and read with hindsight: a linear-chain CRF and a plain HMM, each where installed."""
    rows = {CRF: crf_scores(household, sensors, step_minutes), HMM: hmm_scores(household, sensors, step_minutes)}
    return {name: scores for name, scores in rows.items() if scores is not None}


@dataclass(frozen=True, slots=True)
class RecognitionReport:
    """Everything :func:`recognition_report` measured for one home."""

    household: str
    learning: list[dict[str, Any]]
    asking: list[dict[str, Any]]
    library: dict[str, Scores]  # :func:`library_rows`
    scores: Scores  # online recognition from every labelled training day, on the test days
    settings: dict[str, Any]
    end_to_end: dict[str, Any]


def recognition_report(household: Household, sensors: SensorData, step_minutes: int,
                       counts: Sequence[int | None] = LEARNING_DAYS, budgets: Sequence[int] = BUDGETS,
                       asking_from: int = 3, progress: Callable[[str], None] | None = None) -> RecognitionReport:
    """The learning curve, the asking curve (from ``asking_from`` labelled days; skipped with
    fewer training days), the library rows (:func:`library_rows`), the scores and confusion of the
    recogniser trained on every training day, and the end-to-end effect on the clock model's
    predictions, for one home."""
    from globe.models.clock import ClockModel

    def say(text: str) -> None:
        if progress:
            progress(f"{household.name}: {text}")
    say("the learning curve (settings chosen by cross-validation at each point)")
    recogniser = fit_recogniser(list(household.train), sensors, step_minutes)
    learning = learning_curve(household, sensors, step_minutes, counts, fitted=recogniser)
    asking: list[dict[str, Any]] = []
    if len(household.train) > asking_from:
        say(f"the asking curve ({asking_from} labelled days, {', '.join(map(str, budgets))} questions a day)")
        asking = asking_curve(household, sensors, step_minutes, labelled_days=asking_from, budgets=budgets)
    say("the CRF and plain HMM rows")
    library = library_rows(household, sensors, step_minutes)
    predicted = recogniser.predict(household.test)
    scores = recognition_scores(_flat(household.test), [a for p in predicted for a in p])
    say("the end-to-end effect")
    model = ClockModel(step_minutes=step_minutes).fit([d.activities for d in household.train],
                                                      [d.weekday for d in household.train])
    return RecognitionReport(household.name, learning, asking, library, scores, recogniser.describe(),
                             end_to_end(model, household.test, predicted, recogniser.predictive(household.test),
                                        recogniser.labels))


def write_recognition(report: RecognitionReport, out: Path) -> list[Path]:
    """``recognition.csv`` (the learning curve, the library rows), ``asking.csv``, ``per_class.csv`` and
    ``confusion.png`` (rows: the annotated activity, each row's shares) under ``out``/household."""
    folder = out / report.household
    folder.mkdir(parents=True, exist_ok=True)
    rows = [{"model": "globe (naive Bayes + clock)", **{k: v for k, v in r.items() if k != "settings"},
             "settings": json.dumps(r["settings"], sort_keys=True)} for r in report.learning]
    for name, scores in report.library.items():
        rows.append({"model": name, "labelled_days": report.learning[-1]["labelled_days"] if report.learning else "",
                     **scores.row()})
    written = [_write_csv(folder / "recognition.csv", rows)]
    if report.asking:
        written.append(_write_csv(folder / "asking.csv", report.asking))
    written.append(_write_csv(folder / "per_class.csv", [
        {"activity": a, "steps": int(report.scores.confusion[i].sum()), "f1": round(report.scores.f1.get(a, 0.0), 4)}
        for i, a in enumerate(report.scores.labels) if report.scores.confusion[i].sum()]))
    written.append(_write_csv(folder / "end_to_end.csv", [report.end_to_end]))
    written.append(plot_confusion(report.scores, folder / "confusion.png", report.household))
    return written


def _write_csv(path: Path, rows: Sequence[Mapping[str, Any]]) -> Path:
    columns: list[str] = []
    for row in rows:
        columns += [k for k in row if k not in columns]
    with path.open("w", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, fieldnames=columns, lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)
    return path


def plot_confusion(scores: Scores, path: Path, title: str = "") -> Path:
    """The confusion matrix as shares of each annotated activity's steps (rows sum to 1), with the
    activity's time-slice share beside its name: where recognition goes wrong, at a glance."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    support = scores.confusion.sum(axis=1)
    keep = support > 0
    shares = scores.confusion[keep] / support[keep, None]
    rows = [f"{a} ({s / support.sum():.0%})" for a, s in zip(np.array(scores.labels)[keep], support[keep])]
    size = max(4.0, 0.45 * len(scores.labels) + 2)
    fig, ax = plt.subplots(figsize=(size + 1.5, size))
    image = ax.imshow(shares, cmap="Blues", vmin=0, vmax=1, aspect="auto")
    ax.set_xticks(range(len(scores.labels)), scores.labels, rotation=60, ha="right")
    ax.set_yticks(range(len(rows)), rows)
    for i in range(shares.shape[0]):
        for j in range(shares.shape[1]):
            if shares[i, j] >= 0.01:
                ax.text(j, i, f"{shares[i, j]:.2f}", ha="center", va="center", fontsize=7,
                        color="white" if shares[i, j] > 0.6 else "black")
    ax.set_xlabel("recognised")
    ax.set_ylabel("annotated (share of steps)")
    head = f"{title}: " if title else ""
    ax.set_title(f"{head}time-slice {scores.time_slice:.2f}, class {scores.class_accuracy:.2f}")
    fig.colorbar(image, ax=ax, fraction=0.04)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
