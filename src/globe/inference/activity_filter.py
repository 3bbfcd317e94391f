"""A forward filter over the current activity when activity labels are missing.

A robot rarely gets an activity label for every step. Feeding its best guess back as if it were
the truth throws away what the model is unsure about, so the filter keeps a distribution over the
day's possible activity *histories* instead, for many days at once:

- **Transition.** Each history is extended by the activity model's own next-step distribution,
  through its state space (:mod:`globe.models.state_space`): for the routine model its stay
  hazard, its n-gram over runs and its time-of-day start prior; for the n-gram model its backoff.
- **Evidence.** A visible label pins the activity of its step. The objects seen moving at a
  step are scored by :class:`~globe.inference.emission.MovementEmission`, so "nothing moved" is
  evidence too.
- **State.** Histories that reach the same state of the model have the same future and are
  merged exactly (:func:`globe.inference.beam.advance`); at most ``max_hypotheses`` are kept per
  day, those below ``min_weight`` of the best dropped. With no pruning this is the exact forward
  algorithm; with every label visible it gives exactly the model's ``scan_proba``.

A :class:`Belief` is an immutable value: updating returns a new one, so looking one step ahead
(what the places seen now say about the activity under way) costs no copy.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from globe.data.records import Day
from globe.errors import ConfigError
from globe.inference.beam import Beam, Evidence, advance, tie_key
from globe.inference.emission import MovementEmission
from globe.models.state_space import StateSpace, state_space
from globe.models.vocabulary import Vocabulary
from globe.sequences.movements import moved_objects


@dataclass(frozen=True, slots=True)
class Belief:
    """What the filter knows after ``step`` (-1: nothing yet) about each of ``queries`` days:
    its weighted histories (``beams[-1]``; every earlier beam is kept for the histories), how
    long each history's current run has lasted (``duration``, in steps) and, when they differ
    by day, each day's movement evidence (``emissions``)."""

    step: int
    queries: int
    beams: tuple[Beam, ...]
    duration: np.ndarray
    emissions: tuple[MovementEmission | None, ...] | None = None

    @property
    def beam(self) -> Beam:
        return self.beams[-1]


@dataclass(frozen=True, slots=True)
class Hypothesis:
    """One possible history a_0..a_step of a day, with its posterior weight."""

    weight: float
    history: tuple[str, ...]


Moved = frozenset[str] | None
"""Objects seen moving at a step, or None (not looked)."""


class ActivityFilter:
    """The belief over each day's activities, updated one step at a time (see module doc).

    ``start(n)`` is the belief before the first step of ``n`` days; ``update(belief, step,
    labels, moved)`` conditions it on what was seen at ``step`` (0, 1, ... from the day start) in
    each day: its activity label or None, and the objects seen moving since the step before (or
    None when object places were not observed). ``predictive(belief)`` is then P(a_{step+1} |
    all seen so far) and ``posterior(belief)`` P(a_step | all seen so far), both (days x
    ``labels``). Skipped steps are filled with "nothing seen"."""

    def __init__(self, model: Any, emission: MovementEmission | None = None, *, max_hypotheses: int = 32,
                 min_weight: float = 1e-4, change_floor: float = 0.0) -> None:
        if max_hypotheses < 1:
            raise ConfigError(f"ActivityFilter: max_hypotheses={max_hypotheses}; expected a positive integer")
        if not 0.0 <= min_weight < 1.0:
            raise ConfigError(f"ActivityFilter: min_weight={min_weight}; expected a number in [0, 1)")
        if not 0.0 <= change_floor < 1.0:
            raise ConfigError(f"ActivityFilter: change_floor={change_floor}; expected a number in [0, 1)")
        self.model = model
        self.emission = emission
        self.max_hypotheses = max_hypotheses
        self.min_weight = min_weight
        self.change_floor = change_floor
        self.space: StateSpace = state_space(model)

    def rows(self, states: np.ndarray) -> np.ndarray:
        """P(the next activity | each of ``states``) as the filter steps: the model's rows, each
        with ``change_floor`` of it spread evenly over the activities. Where sensors are the
        evidence, a change the model never saw (an unsmoothed n-gram gives most none) stays
        possible, so what the sensors show can be read; without it such a model holds the filter
        to a path it remembers, whatever the sensors say."""
        rows = self.space.rows(states)
        if self.change_floor <= 0.0:
            return rows
        spread = rows.sum(axis=1, keepdims=True) / rows.shape[1]
        return (1.0 - self.change_floor) * rows + self.change_floor * spread

    @property
    def labels(self) -> Vocabulary:
        """The activity codes of every distribution the filter returns (columns)."""
        return self.space.labels

    def start(self, queries: int = 1, emissions: Sequence[MovementEmission | None] | None = None,
              weekdays: Sequence[int | None] | None = None) -> Belief:
        """Before the first step of ``queries`` days: one empty history each, at the root of each
        day's day of the week (``weekdays``, Monday 0, when known). ``emissions`` (one per day)
        replace the filter's movement evidence, day by day (candidates compared at once)."""
        if not self.space.current():
            self.space = state_space(self.model)
        if emissions is not None and len(emissions) != queries:
            raise ValueError(f"{len(emissions)} movement evidences for {queries} days")
        if weekdays is not None and len(weekdays) != queries:
            raise ValueError(f"{len(weekdays)} days of the week for {queries} days")
        roots = [self.space.root_of(w) for w in weekdays] if weekdays is not None else [self.space.root] * queries
        beam = Beam.roots(np.array(roots, dtype=np.int64))
        return Belief(-1, queries, (beam,), np.zeros(queries, dtype=np.int64),
                      None if emissions is None else tuple(emissions))

    def update(self, belief: Belief, step: int, labels: Sequence[str | None] | None = None,
               moved: Sequence[Moved] | None = None, likelihood: np.ndarray | None = None,
               edges: np.ndarray | None = None) -> Belief:
        """``belief`` conditioned on what was seen at ``step`` in each day (see the class doc);
        ``likelihood`` (days x :attr:`labels`, at most 1): other evidence of the activity at
        ``step`` in each day, such as what the home's sensors showed
        (:class:`~globe.recognition.emission.SensorEmission`); ``edges`` (days x :attr:`labels`
        x :attr:`labels`, at most 1): evidence on each change from the activity at the step before
        to the one at ``step``, such as what the step before showed of the change
        (:class:`~globe.recognition.edges.SensorEdges`)."""
        if step <= belief.step:
            raise ValueError(f"step {step} is not after the last updated step {belief.step}")
        while belief.step + 1 < step:
            belief = self._advance(belief, None, None)
        return self._advance(belief, labels, moved, likelihood, edges)

    def _advance(self, belief: Belief, labels: Sequence[str | None] | None, moved: Sequence[Moved] | None,
                 likelihood: np.ndarray | None = None, edges: np.ndarray | None = None) -> Belief:
        space, beam = self.space, belief.beam
        pinned = None
        if labels is not None:
            if len(labels) != belief.queries:
                raise ValueError(f"{len(labels)} labels for {belief.queries} days")
            pinned = np.array([-1 if a is None else space.code(a) for a in labels], dtype=np.int64)
        rows = self.rows(beam.state)  # first: a model may name a label it never saw
        evidence = self._evidence(belief, moved) if moved is not None and belief.step >= 0 else None
        if likelihood is not None:
            evidence = _with_likelihood(evidence, np.asarray(likelihood, dtype=np.float64), belief.queries,
                                        len(space.labels))
        if edges is not None and belief.step >= 0:
            evidence = _with_edges(evidence, np.asarray(edges, dtype=np.float64), belief.queries, len(space.labels))
        nxt = advance(beam, space, merge=True, floor=self.min_weight, keep=self.max_hypotheses, rows=rows,
                      evidence=evidence, labels=pinned)
        same = nxt.act == beam.act[nxt.parent]
        duration = np.where(same, belief.duration[nxt.parent] + 1, 0)
        return Belief(belief.step + 1, belief.queries, belief.beams + (nxt,), duration, belief.emissions)

    def _evidence(self, belief: Belief, moved: Sequence[Moved]) -> Evidence | None:
        """Each day's movement likelihoods (none where nothing was observed or there is no
        movement evidence)."""
        if len(moved) != belief.queries:
            raise ValueError(f"moved objects of {len(moved)} days for {belief.queries} days")
        labels = self.space.labels
        width = len(labels)
        tables: list[np.ndarray] = [np.ones((width + 1, width))]
        index: dict[tuple[int, frozenset[str]], int] = {}
        which = np.zeros(belief.queries, dtype=np.int64)
        for q, seen in enumerate(moved):
            emission = self.emission if belief.emissions is None else belief.emissions[q]
            if seen is None or emission is None:
                continue
            key = (id(emission), seen)
            i = index.get(key)
            if i is None:
                i = index[key] = len(tables)
                tables.append(emission.likelihoods(labels, seen))
            which[q] = i
        return None if len(tables) == 1 else Evidence(np.stack(tables), which)

    def subset(self, belief: Belief, queries: Sequence[int]) -> Belief:
        """The belief about some of the days only (numbered 0.. in the order given); their earlier
        histories are not kept (:meth:`hypotheses` reads the last step only)."""
        beam = belief.beam
        pick = np.asarray(queries, dtype=np.int64)
        number = np.full(belief.queries, -1, dtype=np.int64)
        number[pick] = np.arange(len(pick))
        mine = np.flatnonzero(number[beam.query] >= 0)
        mine = mine[np.argsort(number[beam.query[mine]], kind="stable")]
        part = Beam(number[beam.query[mine]], beam.weight[mine], beam.state[mine], beam.act[mine],
                    np.full(len(mine), -1, dtype=np.int64), beam.lex[mine])
        emissions = None if belief.emissions is None else tuple(belief.emissions[q] for q in queries)
        return Belief(belief.step, len(pick), (part,), belief.duration[mine], emissions)

    # -- reading a belief ----------------------------------------------------------------------
    def predictive(self, belief: Belief, edges: np.ndarray | None = None) -> np.ndarray:
        """(days x labels): P(the activity at the next step | everything seen so far); ``edges``
        (days x labels x labels, as :meth:`update` takes them): what the last step showed of each
        change after it, which the next update would take in."""
        beam = belief.beam
        rows = self.rows(beam.state) * beam.weight[:, None]
        if edges is not None and belief.step >= 0:
            e = np.asarray(edges, dtype=np.float64)
            k = e.shape[1]
            here = (beam.act >= 0) & (beam.act < k)
            rows[here, :k] *= e[beam.query[here], beam.act[here]]
        out = np.zeros((belief.queries, rows.shape[1]))
        np.add.at(out, beam.query, rows)
        total = out.sum(axis=1, keepdims=True)
        return np.divide(out, total, out=np.zeros_like(out), where=total > 0)

    def posterior(self, belief: Belief) -> np.ndarray:
        """(days x labels): P(the activity at the last updated step | everything seen so far)."""
        beam = belief.beam
        width = len(self.space.labels)
        seen = beam.act >= 0
        cells = beam.query[seen] * width + beam.act[seen]
        return np.bincount(cells, weights=beam.weight[seen], minlength=belief.queries * width).reshape(-1, width)

    def hypotheses(self, belief: Belief, query: int = 0) -> list[Hypothesis]:
        """The weighted histories a_0..a_step kept for day ``query`` (most probable first)."""
        beam = belief.beam
        memo = HistoryMemo()  # they share most of their past: each is read against the first
        return [Hypothesis(float(beam.weight[i]), self.history(belief, i, memo=memo, keep=k == 0))
                for k, i in enumerate(np.flatnonzero(beam.query == query).tolist())]

    def top_histories(self, belief: Belief, most: int, query: int = 0,
                      memo: "HistoryMemo | None" = None) -> list[Hypothesis]:
        """The ``most`` most probable histories a_0..a_step of day ``query`` (ties: in history
        order), their weights renormalised over those kept: what a forecast mixes over. They
        share most of their past, so each is read through one ``memo`` (:meth:`history`)."""
        beam = belief.beam
        mine = np.flatnonzero(beam.query == query)
        order = mine[np.lexsort((beam.lex[mine], -tie_key(beam.weight[mine])))][:most]
        total = float(beam.weight[order].sum())
        memo = HistoryMemo() if memo is None else memo
        return [Hypothesis(float(beam.weight[i]) / total, self.history(belief, int(i), memo=memo, keep=k == 0))
                for k, i in enumerate(order.tolist())]

    def history(self, belief: Belief, entry: int, steps: int | None = None,
                memo: "HistoryMemo | None" = None, keep: bool = True) -> tuple[str, ...]:
        """The activities of the last beam's ``entry``, the first ``steps`` of them (all: None).
        With ``memo`` (the last history read through it), the walk back stops where this history
        meets that one: a session reading its most probable history at every step walks a step
        or two, not the whole day; ``keep=False`` leaves the memo as it was (the histories that
        branch off the most probable one are read against it)."""
        if memo is None:  # nothing read before: the whole walk, nothing kept
            memo, keep = HistoryMemo(), False
        beams, names = belief.beams, self.space.labels
        level, found = len(beams) - 1, []
        while level >= 1 and not (level < len(memo.beams) and memo.beams[level] is beams[level]
                                  and memo.entries[level - 1] == entry):
            beam = beams[level]
            found.append((entry, names[int(beam.act[entry])]))
            entry = int(beam.parent[entry])
            level -= 1
        if not keep:
            history = (*memo.names[:level], *(name for _, name in reversed(found)))
            return history if steps is None else history[:steps]
        del memo.entries[level:], memo.names[level:]
        for entry, name in reversed(found):
            memo.entries.append(entry)
            memo.names.append(name)
        memo.beams = beams
        history = tuple(memo.names)
        return history if steps is None else history[:steps]


class HistoryMemo:
    """The last history :meth:`ActivityFilter.history` read through it: the beams it was read
    from and, per step, the entry and the activity of its path. Histories of one growing belief
    share their past (its beams are kept, never changed), so two paths that pass through the
    same entry of the same beam agree on every step before it."""

    __slots__ = ("beams", "entries", "names")

    def __init__(self) -> None:
        self.beams: tuple[Beam, ...] = ()
        self.entries: list[int] = []
        self.names: list[str] = []


def _with_likelihood(evidence: Evidence | None, likelihood: np.ndarray, queries: int, width: int) -> Evidence:
    """``evidence`` times each day's likelihood of the current activity (the same whatever came before)."""
    if likelihood.shape != (queries, width):
        if likelihood.ndim == 2 and likelihood.shape[0] == queries and likelihood.shape[1] < width:
            likelihood = np.pad(likelihood, ((0, 0), (0, width - likelihood.shape[1])), constant_values=1.0)
        else:
            raise ValueError(f"likelihoods of shape {likelihood.shape} for {queries} days and {width} activities")
    return _times(evidence, np.broadcast_to(likelihood[:, None, :], (queries, width + 1, width)))


def _with_edges(evidence: Evidence | None, edges: np.ndarray, queries: int, width: int) -> Evidence:
    """``evidence`` times each day's evidence on each (previous activity, activity) pair; labels
    the edges do not name (the filter's grew) read 1, as does a history with no previous activity."""
    if edges.ndim != 3 or edges.shape[0] != queries or edges.shape[1] != edges.shape[2] or edges.shape[1] > width:
        raise ValueError(f"edges of shape {edges.shape} for {queries} days and {width} activities")
    rows = np.ones((queries, width + 1, width))
    rows[:, : edges.shape[1], : edges.shape[2]] = edges
    return _times(evidence, rows)


def _times(evidence: Evidence | None, tables: np.ndarray) -> Evidence:
    """``evidence`` times each day's own table (days x (previous activity or none) x activity)."""
    if evidence is None:
        return Evidence(np.concatenate([np.ones((1, *tables.shape[1:])), tables]), np.arange(1, len(tables) + 1))
    return Evidence(evidence.tables[evidence.table_of] * tables, np.arange(len(tables)))


def smoothed(flt: "ActivityFilter", belief: Belief) -> np.ndarray:
    """(days x steps x :attr:`ActivityFilter.labels`): P(a_t | everything seen up to the last
    step) for every step t, from the histories the filter kept at the end (a label past days
    read with hindsight). Exact without pruning or merging; with them, histories merged into a
    heavier one lend it their weight (as a Viterbi path keeps the best way to a state)."""
    steps = len(belief.beams) - 1
    out = np.zeros((belief.queries, steps, len(flt.labels)))
    beam = belief.beam
    entries = np.arange(len(beam), dtype=np.int64)
    weight, query = beam.weight, beam.query
    for t in range(steps - 1, -1, -1):
        level = belief.beams[t + 1]
        np.add.at(out, (query, np.full(len(query), t), np.maximum(level.act[entries], 0)), weight)
        entries = level.parent[entries]
    return out


def as_dicts(rows: np.ndarray, labels: Sequence[str]) -> list[dict[str, float]]:
    """Each row as {label: probability} over its nonzero entries, in code order."""
    names = list(labels)
    return [{names[i]: p for i, p in enumerate(row) if p} for row in rows.tolist()]


def filtered_beliefs(flt: ActivityFilter, days: Sequence[Day], visible: Sequence[Sequence[bool]],
                     objects: Sequence[str], *, nowcast: bool = False, predictive: bool = True,
                     emissions: Sequence[MovementEmission | None] | None = None
                     ) -> tuple[list[np.ndarray] | None, list[np.ndarray] | None]:
    """Run ``flt`` over ``days`` at once (``emissions``: each day's movement evidence, when they
    differ). Returns, per day, (steps x ``flt.labels``): the predictive P(a_t | visible labels
    of steps < t, movements seen at steps < t) (None without ``predictive``) and, with
    ``nowcast``, P(a_t | the same and the movements seen at step t) (what is known about the
    activity under way once the objects' places at t are seen, before its label would arrive)."""
    if len(visible) != len(days):
        raise ValueError(f"{len(visible)} label masks for {len(days)} days")
    for day, mask in zip(days, visible):
        if len(mask) != len(day):
            raise ValueError(f"the label mask has {len(mask)} steps; the day {day.name} has {len(day)}")
    moved_sets = [moved_objects(day, objects) for day in days]
    steps = max((len(d) for d in days), default=0)
    belief = flt.start(len(days), emissions, [d.weekday for d in days])
    ahead: list[list[np.ndarray]] = [[] for _ in days]
    now: list[list[np.ndarray]] = [[] for _ in days]
    for t in range(steps):
        moved = [m[t] if t < len(m) else None for m in moved_sets]
        labels = [d.activities[t] if t < len(d) and m[t] else None for d, m in zip(days, visible)]
        if predictive:
            _append_rows(ahead, flt.predictive(belief), days, t)
        after = flt.update(belief, t, labels, moved)
        if nowcast:  # where no label shows, the update is the nowcast; elsewhere, look without it
            rows = flt.posterior(after)
            seen = [q for q, a in enumerate(labels) if a is not None]
            if seen:
                peek = flt.update(flt.subset(belief, seen), t, None, [moved[q] for q in seen])
                looked = flt.posterior(peek)
                width = max(rows.shape[1], looked.shape[1])
                rows = np.pad(rows, ((0, 0), (0, width - rows.shape[1])))
                rows[seen] = np.pad(looked, ((0, 0), (0, width - looked.shape[1])))
            _append_rows(now, rows, days, t)
        belief = after
    width = len(flt.labels)
    stack = [_stack(rows, width) for rows in ahead] if predictive else None
    return stack, ([_stack(rows, width) for rows in now] if nowcast else None)


def _append_rows(out: list[list[np.ndarray]], rows: np.ndarray, days: Sequence[Day], t: int) -> None:
    for q, day in enumerate(days):
        if t < len(day):
            out[q].append(rows[q])


def _stack(rows: list[np.ndarray], width: int) -> np.ndarray:
    """Rows of different widths (the labels grew) as one (steps x width) array."""
    out = np.zeros((len(rows), width))
    for i, row in enumerate(rows):
        out[i, : len(row)] = row
    return out


def label_mask(n: int, fraction: float, seed: Sequence[int]) -> list[bool]:
    """Which of ``n`` steps show their label: ``round(fraction * n)`` of them, drawn with ``seed``.
    Masks of one seed are nested (a larger fraction shows a superset), so fractions compare fairly."""
    order = np.random.default_rng(list(seed)).permutation(n)
    k = round(fraction * n)
    out = [False] * n
    for i in order[:k]:
        out[int(i)] = True
    return out
