"""P(activity at step t | the home's sensors up to t): GLOBE's activity filter with sensor evidence.

The recogniser is a hidden Markov model whose dynamics are the household's own activity model
(by default the clock model: P(a_t | a_{t-1}, time of day), counted on labelled days) and whose
emission is naive Bayes over the step features of :mod:`globe.recognition.features`
(:class:`~globe.recognition.emission.SensorEmission`), or a classifier's scaled likelihood as in
hybrid HMMs (:class:`~globe.recognition.hybrid.DiscriminativeEmission`) where cross-validation
prefers it (``RecognitionSettings.emission``). It runs on the same
:class:`~globe.inference.activity_filter.ActivityFilter` that infers missing labels from object
movements, so online recognition (filtering: no look-ahead, what the service can know at a step)
and a label seen now and then (an answered question) need no new inference code. With
hindsight (labelling past days, self-training) the labels are the most probable sequence
(:meth:`Recogniser.decode`: the histories the filter kept, as a Viterbi path), and how sure each
step's label is comes from exact forward-backward (:meth:`Recogniser.smooth`: the dynamics are
first order, so P(a_t | the whole day) sums over every path).

With ``edges``, a step's features are also read as evidence on the change after it
(:class:`~globe.recognition.edges.SensorEdges`): the filter takes them on each transition into
the next step, so a change is recognised with what the step before showed of it.

Few labels: with ``self_training``, days without labels are recognised (smoothed) and their
confident steps (posterior at least ``confidence``) counted into the emission, weighted by their
posterior; whether that helps is for cross-validation to say (:mod:`globe.recognition.selection`).
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from typing import Any, Callable, Literal, Sequence

import numpy as np

from globe.data.records import Day
from globe.data.sensors import SensorData
from globe.inference.activity_filter import ActivityFilter, smoothed
from globe.models.clock import ClockModel
from globe.recognition.edges import SensorEdges
from globe.recognition.emission import SensorEmission
from globe.recognition.features import Layout, step_features
from globe.recognition.hybrid import DiscriminativeEmission

EmissionKind = Literal["naive_bayes", "discriminative"]
EMISSIONS: tuple[EmissionKind, ...] = ("naive_bayes", "discriminative")

Answers = Sequence[Sequence[str | None]]
"""Per day, per step: an activity someone said (a label or an answered question), or None."""


@dataclass(frozen=True, slots=True)
class RecognitionSettings:
    """What cross-validation chooses for a home's recogniser."""

    features: tuple[str, ...] = ("change", "last")
    weight: float = 1.0
    smoothing: float = 1.0
    self_training: bool = False
    confidence: float = 0.9
    slot_minutes: int = 60
    shrinkage: float = 5.0
    emission: EmissionKind = "naive_bayes"
    edges: bool = False  # each step's features also read as evidence on the change after it
    edge_strength: float = 10.0  # pseudo-steps shrinking a change's evidence to its activity's own


def sensor_emission(settings: RecognitionSettings) -> SensorEmission | DiscriminativeEmission:
    """The (unfitted) sensor emission ``settings`` name: naive Bayes, or the discriminative one."""
    if settings.emission == "discriminative":
        return DiscriminativeEmission(weight=settings.weight)
    if settings.emission != "naive_bayes":
        raise ValueError(f"unknown sensor emission {settings.emission!r}; expected one of {', '.join(EMISSIONS)}")
    return SensorEmission(smoothing=settings.smoothing, weight=settings.weight)


def sensor_edges(settings: RecognitionSettings) -> SensorEdges | None:
    """The (unfitted) evidence on changes ``settings`` ask for (None: none), tempered as the emission."""
    if not settings.edges:
        return None
    return SensorEdges(strength=settings.edge_strength, smoothing=settings.smoothing, weight=settings.weight)


class Recogniser:
    """The recogniser of one home (see module doc): ``fit`` on labelled days, then ``filter`` or
    ``smooth`` any days of the home (by their sensor activations)."""

    def __init__(self, settings: RecognitionSettings | None = None, *, max_hypotheses: int = 16,
                 min_weight: float = 1e-4) -> None:
        self.settings = settings or RecognitionSettings()
        self.max_hypotheses = max_hypotheses
        self.min_weight = min_weight

    # -- fitting -------------------------------------------------------------------------------
    def fit(self, days: Sequence[Day], sensors: SensorData, step_minutes: int, unlabelled: Sequence[Day] = (),
            answers: Answers | None = None) -> "Recogniser":
        """Learn the dynamics and the emission from ``days`` (their activities are the labels);
        with self-training, or where ``answers`` (one per ``unlabelled`` day: what the person
        said at a few steps) are given, also from the ``unlabelled`` days as recognised with
        hindsight, the answers pinned: their confident steps count in the emission, weighted by
        their posterior, and their most probable activities in the dynamics."""
        if not days:
            raise ValueError("the recogniser needs at least one labelled day")
        if answers is not None and len(answers) != len(unlabelled):
            raise ValueError(f"answers for {len(answers)} days, {len(unlabelled)} unlabelled days")
        s = self.settings
        self.sensors_ = sensors
        self.step_minutes_ = step_minutes
        self.layout_ = Layout.of(sensors.sensors, s.features)
        features = [self.features(d) for d in days]
        self._fit_parts([d.activities for d in days], [d.weekday for d in days], features,
                        [np.ones(len(d)) for d in days])
        self.labelled_ = Counter(a for d in days for a in d.activities)
        if unlabelled and (s.self_training or answers is not None):
            if answers is not None:
                answers = self._spread(unlabelled, answers)
                self.labelled_.update(a for said in answers for a in said if a is not None)
            paths, posts = self.decode(unlabelled, answers), self.smooth(unlabelled, answers)
            names = self.labels  # after reading them: the answers may have named new activities
            guessed: list[Sequence[str]] = []
            confident: list[Sequence[str | None]] = []
            weights = []
            for path, post in zip(paths, posts):
                best = path.argmax(axis=1)
                top = post[np.arange(len(best)), best]  # how sure the step's label is, every path summed
                guessed.append(tuple(names[b] for b in best.tolist()))
                confident.append([names[b] if p >= s.confidence else None for b, p in zip(best.tolist(), top.tolist())])
                weights.append(top)
            self._fit_parts([*(d.activities for d in days), *guessed],
                            [d.weekday for d in days] + [d.weekday for d in unlabelled],
                            features + [self.features(d) for d in unlabelled],
                            [np.ones(len(d)) for d in days] + weights,
                            [*(d.activities for d in days), *confident])
        return self

    def _spread(self, days: Sequence[Day], answers: Answers) -> list[list[str | None]]:
        """Each answer taken as the activity of the whole stretch around it that the recogniser
        read as one activity (its most probable activity unchanged, read with hindsight): the
        person did one thing there, and a stretch read wrong was read wrong for the same reason."""
        return [spread_answers(path.argmax(axis=1).tolist(), said) for path, said in zip(self.decode(days), answers)]

    def _fit_parts(self, sequences: Sequence[Sequence[str]], weekdays: Sequence[int | None],
                   features: Sequence[np.ndarray], weights: Sequence[np.ndarray],
                   labels: Sequence[Sequence[str | None]] | None = None) -> None:
        s = self.settings
        self.dynamics_ = ClockModel(slot_minutes=s.slot_minutes, shrinkage=s.shrinkage, step_minutes=self.step_minutes_)
        self.dynamics_.fit(sequences, weekdays)
        counted = sequences if labels is None else labels
        self.emission_ = sensor_emission(s).fit(features, counted, self.layout_.sizes, weights)
        edges = sensor_edges(s)
        self.edges_ = None if edges is None else edges.fit(features, counted, self.layout_.sizes, weights)
        self.filter_ = ActivityFilter(self.dynamics_, max_hypotheses=self.max_hypotheses, min_weight=self.min_weight)

    def features(self, day: Day) -> np.ndarray:
        """The (steps x columns) sensor features of ``day``."""
        return step_features(self.layout_, self.sensors_.of(day.name), day.minutes, self.step_minutes_)

    def labelled_counts(self) -> np.ndarray:
        """Per activity of :attr:`labels`: the steps labelled in ``fit`` (the labelled days', and the
        answers' spread over their stretches), what :func:`~globe.recognition.asking.worth` weighs."""
        return np.array([self.labelled_.get(a, 0) for a in self.labels], dtype=np.float64)

    @property
    def labels(self) -> tuple[str, ...]:
        """The activities of every distribution returned (columns)."""
        return tuple(self.filter_.labels)

    # -- recognising ---------------------------------------------------------------------------
    def filter(self, days: Sequence[Day], answers: Answers | None = None) -> list[np.ndarray]:
        """Per day, (steps x :attr:`labels`): P(a_t | sensors up to t, answers up to t)."""
        return self._run(days, answers, "filter")

    def smooth(self, days: Sequence[Day], answers: Answers | None = None) -> list[np.ndarray]:
        """Per day, (steps x :attr:`labels`): P(a_t | the whole day's sensors and answers), every
        path summed (:func:`forward_backward`): how sure a label read with hindsight is."""
        return self._run(days, answers, "smooth")

    def decode(self, days: Sequence[Day], answers: Answers | None = None) -> list[np.ndarray]:
        """Per day, (steps x :attr:`labels`): the weight of the histories the filter kept at the
        day's end through each activity at each step (:func:`~globe.inference.activity_filter.smoothed`:
        the best way to each state, as a Viterbi path), whose argmax is the most probable *sequence*:
        the labels read with hindsight (whole stretches, where per-step marginals may flicker)."""
        return self._run(days, answers, "decode")

    def predictive(self, days: Sequence[Day], answers: Answers | None = None) -> list[np.ndarray]:
        """Per day, (steps x :attr:`labels`): P(a_{t+1} | sensors up to t): what the activity
        model expects next from everything the sensors said, not from one guessed history."""
        return self._run(days, answers, "predictive")

    def predict(self, days: Sequence[Day], answers: Answers | None = None, *, smooth: bool = False) -> list[list[str]]:
        """The most probable activity at each step of each day: online, or with ``smooth`` the
        most probable sequence read with hindsight (:meth:`decode`)."""
        names = self.labels
        rows = self._run(days, answers, "decode" if smooth else "filter")
        return [[names[i] for i in r.argmax(axis=1).tolist()] for r in rows]

    def _evidence(self, day: Day, labels: Sequence[str]) -> tuple[np.ndarray, np.ndarray | None]:
        """The day's sensor likelihoods (steps x ``labels``) and, with edges, each step's evidence
        on the change after it (steps x ``labels`` x ``labels``)."""
        features = self.features(day)
        edges = None if self.edges_ is None else self.edges_.tables(features, labels)
        return self.emission_.likelihoods(features, labels), edges

    def _run(self, days: Sequence[Day], answers: Answers | None, mode: Mode) -> list[np.ndarray]:
        labels = list(self.filter_.labels)
        read = [self._evidence(d, labels) for d in days]
        likes = [lk for lk, _ in read]
        edges = None if self.edges_ is None else [e for _, e in read if e is not None]
        if mode == "smooth":
            said = answers if answers is not None else [()] * len(days)
            return [forward_backward(self.filter_, pinned(lk, a, labels), d.weekday, e)
                    for d, (lk, e), a in zip(days, read, said)]
        return run_days(self.filter_, likes, [d.weekday for d in days], answers, mode, edges)

    def filter_asking(self, day: Day, ask: Callable[[int, np.ndarray], bool],
                      answer: Callable[[int], str | None]) -> tuple[np.ndarray, list[str | None]]:
        """The online loop with questions: at each step of ``day`` the sensors' evidence is taken
        in, then ``ask(step, posterior)`` says whether to ask; if so ``answer(step)`` (the person,
        or an annotation standing in for them; None: no answer) pins the step. Returns the
        (steps x :attr:`labels`) posteriors after any answer, and the answers per step."""
        flt = self.filter_
        names = list(flt.labels)
        likes, edges = self._evidence(day, names)
        belief = flt.start(1, weekdays=[day.weekday])
        out = np.zeros((len(day), len(names)))
        said: list[str | None] = [None] * len(day)
        for t in range(len(day)):
            like = likes[t][None, :]
            edge = edges[t - 1][None] if edges is not None and t else None
            after = flt.update(belief, t, None, likelihood=like, edges=edge)
            post = flt.posterior(after)[0]
            if ask(t, post):
                said[t] = answer(t)
                if said[t] is not None:
                    after = flt.update(belief, t, [said[t]], likelihood=like, edges=edge)
                    post = flt.posterior(after)[0]
            out[t, : len(post)] = post[: out.shape[1]]
            belief = after
        return out, said

    def describe(self) -> dict[str, Any]:
        s = self.settings
        edges = {"edges": s.edges, **({"edge_strength": s.edge_strength} if s.edges else {})}
        return {"features": list(s.features), "emission": s.emission, "weight": s.weight, "smoothing": s.smoothing,
                "self_training": s.self_training, **edges, "dynamics": f"clock ({s.slot_minutes}-min slots)"}


def spread_answers(best: Sequence[int], said: Sequence[str | None]) -> list[str | None]:
    """Each label in ``said`` taken as the activity of the whole stretch around it whose most
    probable activity (``best``, read with hindsight) stays the same and is unlabelled."""
    spread: list[str | None] = list(said)
    for t, answer in enumerate(said):
        if answer is None:
            continue
        lo = t
        while lo > 0 and best[lo - 1] == best[t] and said[lo - 1] is None:
            lo -= 1
        hi = t
        while hi + 1 < len(best) and best[hi + 1] == best[t] and said[hi + 1] is None:
            hi += 1
        for i in range(lo, hi + 1):
            if said[i] is None:
                spread[i] = answer
    return spread


Mode = Literal["filter", "smooth", "decode", "predictive"]


def pinned(likelihoods: np.ndarray, said: Sequence[str | None], labels: Sequence[str]) -> np.ndarray:
    """``likelihoods`` (steps x ``labels``) with each step someone said the activity of (``said``)
    left only that activity's: an answer pins its step, as a label does in the filter."""
    out = likelihoods.copy()
    code = {a: i for i, a in enumerate(labels)}
    for t, a in enumerate(said[: len(out)]):
        if a is not None and a in code:
            keep = out[t, code[a]]
            out[t] = 0.0
            out[t, code[a]] = keep if keep > 0 else 1.0
    return out


def forward_backward(flt: ActivityFilter, likelihoods: np.ndarray, weekday: int | None,
                     edges: np.ndarray | None = None) -> np.ndarray:
    """(steps x ``flt.labels``): P(a_t | every step's evidence, ``likelihoods`` steps x labels) under
    ``flt``'s first-order dynamics (the clock model: the next activity depends on the current one
    and the time), summed over every path by scaled forward and backward passes; the transition at
    step t is the dynamics' row for each previous activity, times ``edges[t - 1]`` where given
    (steps x labels x labels: each step's evidence on the change after it)."""
    flt.start(1, weekdays=[weekday])  # a state space where the dynamics grew
    space, n, steps = flt.space, len(flt.labels), len(likelihoods)
    if not steps:
        return np.zeros((0, n))
    likes = np.ones((steps, n))
    likes[:, : likelihoods.shape[1]] = likelihoods
    codes = np.arange(n, dtype=np.int64)
    state = np.array([space.root_of(weekday)], dtype=np.int64)
    first = flt.rows(state)[0][:n]
    moves: list[np.ndarray] = []  # moves[t - 1]: (previous x next) at step t
    for _ in range(1, steps):
        after = space.children(np.repeat(state[:1], n), codes)  # each previous activity, one step on
        move = flt.rows(after)[:, :n]
        if edges is not None:  # a copy: the rows may be the state space's own
            move = move.copy()
            k = edges.shape[1]
            move[:k, :k] *= edges[len(moves)]
        moves.append(move)
        state = after
    uniform = np.full(n, 1.0 / n)
    forward = np.zeros((steps, n))
    row = first * likes[0]
    for t in range(steps):
        if t:
            row = (forward[t - 1] @ moves[t - 1]) * likes[t]
        total = row.sum()
        forward[t] = row / total if total > 0 else uniform
    backward = np.ones((steps, n))
    for t in range(steps - 2, -1, -1):
        row = moves[t] @ (likes[t + 1] * backward[t + 1])
        total = row.sum()
        backward[t] = row / total if total > 0 else uniform
    post = forward * backward
    return post / np.maximum(post.sum(axis=1, keepdims=True), 1e-300)


def _edges_at(edges: Sequence[np.ndarray] | None, t: int, width: int) -> np.ndarray | None:
    """(days x width x width): each day's evidence of its step ``t`` on the change after it (1 past
    a day's end), or None without edges."""
    if edges is None:
        return None
    out = np.ones((len(edges), width, width))
    for q, e in enumerate(edges):
        if t < len(e):
            out[q, : e.shape[1], : e.shape[2]] = e[t]
    return out


def run_days(flt: ActivityFilter, likelihoods: Sequence[np.ndarray], weekdays: Sequence[int | None],
             answers: Answers | None = None, mode: Literal["filter", "decode", "predictive"] = "filter",
             edges: Sequence[np.ndarray] | None = None) -> list[np.ndarray]:
    """Run ``flt`` over days at once, each step taking in that day's sensor ``likelihoods`` (steps x
    ``flt.labels``), with ``edges`` what the step before showed of each change (per day, steps x
    labels x labels: :meth:`~globe.recognition.edges.SensorEdges.tables`), and its answer, if any.
    Per day, (steps x ``flt.labels``): P(a_t | up to t) (``filter``), the kept histories' weight
    through each activity at the day's end (``decode``:
    :func:`~globe.inference.activity_filter.smoothed`) or P(a_{t+1} | up to t) (``predictive``)."""
    if not likelihoods:
        return []
    belief = flt.start(len(likelihoods), weekdays=list(weekdays))
    width = len(flt.labels)
    out = [np.zeros((len(lk), width)) for lk in likelihoods]
    for t in range(max(len(lk) for lk in likelihoods)):
        like = np.ones((len(likelihoods), width))
        for q, lk in enumerate(likelihoods):
            if t < len(lk):
                like[q, : lk.shape[1]] = lk[t]
        said = None if answers is None else [a[t] if t < len(a) else None for a in answers]
        into = _edges_at(edges, t - 1, width) if t else None  # the step before's, on each change into t
        belief = flt.update(belief, t, said, likelihood=like, edges=into)
        if mode != "decode":  # the predictive also takes this step's, on each change after it
            post = flt.posterior(belief) if mode == "filter" else flt.predictive(belief, _edges_at(edges, t, width))
            for q, lk in enumerate(likelihoods):
                if t < len(lk):
                    out[q][t, : post.shape[1]] = post[q]
    if mode == "decode":
        full = smoothed(flt, belief)
        out = [full[q, : len(lk)] for q, lk in enumerate(likelihoods)]
    return out
