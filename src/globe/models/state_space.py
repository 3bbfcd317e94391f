"""A fitted activity model's states as integers: the one hook inference needs.

Every activity model builds one :class:`StateSpace` (``model.states()``, nltk.lm's idea of one
small hook per model with the rest written once): an integer ``root`` (the state before the
first step of a day), ``children(states, activities)`` (the state after each activity) and
``rows(states)``, the next-step distributions as a (states x labels) array over the codes of
its :class:`~globe.models.vocabulary.Vocabulary`. A state summarises a history exactly:
histories with equal states (and lengths) have the same future, so the activity filter merges
them. ``predict_proba`` and ``scan_proba`` of every model read the same rows, so a model's rule
is written once and reaches the filter and the forecaster with no other edit.

:class:`NumberedStates` serves a model whose states are any hashable values, asked one at a
time (``root_state``, ``advance``, ``next_distribution``); a model whose rule vectorises (the
routine model) implements the arrays itself.
"""

from __future__ import annotations

import weakref
from typing import Any, Callable, Hashable, Sequence

import numpy as np

from globe.models.vocabulary import Vocabulary

MEMO_STATES = 200_000
"""States a space numbers before its model starts a fresh one for new users (memory is bounded)."""


def fit_version(model: Any) -> Hashable:
    """Changes whenever ``model`` is fitted again or learns a day (memos over it are then stale)."""
    version = getattr(model, "fit_version_", None)
    if version is not None:
        return version
    data = getattr(model, "training_data_", ())
    return id(data), len(data)


class StateSpace:
    """The integer states of one fitted model (see module doc). Subclasses implement ``root``,
    :meth:`rows`, :meth:`children` and :meth:`last`; label codes are the model's classes first,
    and a label it never saw (in a history) is appended by :meth:`code`."""

    root: int

    def __init__(self, model: Any, classes: Sequence[str]) -> None:
        self.model = model
        self.version = fit_version(model)
        self.labels = Vocabulary(classes)
        self._name_rank = np.zeros(0, dtype=np.int64)
        self._histories: dict[tuple[str, ...], int] = {}
        self._rooted: dict[int, dict[tuple[str, ...], int]] = {}  # other roots' histories (days of a known type)

    # -- what a model implements ---------------------------------------------------------------
    def rows(self, states: np.ndarray) -> np.ndarray:  # pragma: no cover - abstract
        """(states x labels): P(the next activity | each state); a model with nothing to say
        keeps the last activity (the row of a root may be empty)."""
        raise NotImplementedError

    def children(self, states: np.ndarray, codes: np.ndarray) -> np.ndarray:  # pragma: no cover - abstract
        """The state after each (state, activity code) pair."""
        raise NotImplementedError

    def last(self, states: np.ndarray) -> np.ndarray:  # pragma: no cover - abstract
        """The last activity code of each state's history (-1 before the first step)."""
        raise NotImplementedError

    def root_of(self, weekday: int | None) -> int:
        """The state before the first step of a day of ``weekday`` (Monday 0; None: not known);
        :attr:`root` for a model that does not know the day of the week."""
        return self.root

    def child(self, state: int, code: int) -> int:
        """:meth:`children` of one state (a history is walked one activity at a time)."""
        return int(self.children(np.array([state]), np.array([code]))[0])

    def size(self) -> int:
        """How many states this space remembers (a fresh space is made past :data:`MEMO_STATES`)."""
        return 0

    def _grow_labels(self) -> None:
        """Called when :meth:`code` appended a label: widen whatever is indexed by label code."""

    # -- written once ---------------------------------------------------------------------------
    def current(self) -> bool:
        """Whether this space still describes its model (it has not learnt since) and has room."""
        return fit_version(self.model) == self.version and self.size() <= MEMO_STATES

    def code(self, label: str) -> int:
        """The code of ``label``, appending it when the model never saw it."""
        code = self.labels.get(label)
        if code < 0:
            self.labels = self.labels.extended([label])
            code = len(self.labels) - 1
            self._grow_labels()
        return code

    def name_rank(self) -> np.ndarray:
        """The rank of each label code in name order (histories tie-break by name)."""
        if len(self._name_rank) != len(self.labels):
            order = sorted(range(len(self.labels)), key=self.labels.__getitem__)
            self._name_rank = np.empty(len(order), dtype=np.int64)
            self._name_rank[order] = np.arange(len(order))
        return self._name_rank

    def best(self, states: np.ndarray) -> np.ndarray:
        """The most probable next activity of each state (ties: the larger name; -1: none)."""
        return best_of(self.rows(states), self.name_rank())

    def state(self, history: Sequence[str], weekday: int | None = None) -> int:
        """The state after ``history`` on a day of ``weekday`` (memoised per root; a history one
        activity longer than one asked before is walked from there)."""
        history = tuple(history)
        root = self.root_of(weekday)
        known = self._histories if root == self.root else self._rooted.setdefault(root, {})
        sid = known.get(history)
        if sid is not None:
            return sid
        start = len(history) - 1
        while start > 0 and history[:start] not in known:
            start -= 1
        sid = known.get(history[:start], root) if start > 0 else root
        for activity in history[max(start, 0):]:
            sid = self.child(sid, self.code(activity))
        if len(known) >= MEMO_STATES:
            known.clear()
        known[history] = sid
        return sid

    def path(self, day: Sequence[str], weekday: int | None = None) -> np.ndarray:
        """The state before each step of ``day`` (its root, then after each activity but the last)."""
        out = np.empty(len(day), dtype=np.int64)
        sid = self.root_of(weekday)
        for t, activity in enumerate(day):
            out[t] = sid
            if t + 1 < len(day):
                sid = self.child(sid, self.code(activity))
        return out

    def scan(self, day: Sequence[str], weekday: int | None = None) -> list[dict[str, float]]:
        """The next-step distribution before each step of ``day`` (what ``scan_proba`` answers)."""
        return self.distributions(self.path(day, weekday))

    def distributions(self, states: np.ndarray) -> list[dict[str, float]]:
        """:meth:`rows` as {label: probability} over their nonzero entries, in code order."""
        labels = self.labels.labels
        return [{labels[i]: p for i, p in enumerate(row) if p} for row in self.rows(states).tolist()]


def best_of(rows: np.ndarray, name_rank: np.ndarray) -> np.ndarray:
    """The most probable column of each row (ties: the larger name; -1 for an empty row)."""
    top = rows.max(axis=1, initial=0.0)
    tied = (rows == top[:, None]) & (rows > 0.0)
    pick = np.where(tied, name_rank[None, : rows.shape[1]], -1).argmax(axis=1)
    return np.where(top > 0.0, pick, -1)


def first_met(rows: np.ndarray, cols: np.ndarray, width: int) -> list[tuple[int, int]]:
    """The distinct (row, column) pairs of ``rows`` and ``cols`` (columns below ``width``) in the
    order first met: new children created in this order are numbered as one at a time would be,
    and each once however often it is met."""
    pairs, first = np.unique(rows * width + cols, return_index=True)
    return [divmod(p, width) for p in pairs[np.argsort(first)].tolist()]


class NumberedStates(StateSpace):
    """States of any hashable kind, numbered as they are reached: ``advance(key, step, activity)``
    gives a child's key and ``distribution(key, step)`` a state's next step as a dict, asked once
    per (key, step, last activity) and kept as a dense row."""

    def __init__(self, model: Any, classes: Sequence[str], root: Hashable,
                 advance: Callable[[Any, int, str], Hashable],
                 distribution: Callable[[Any, int], dict[str, float]]) -> None:
        super().__init__(model, classes)
        self._advance, self._distribution = advance, distribution
        self._keys: list[Hashable] = []
        self._ids: dict[tuple[Hashable, int, int], int] = {}
        self._dists: dict[int, dict[str, float]] = {}  # the model's own answers, by state
        width = max(len(self.labels), 1)
        self._step = np.zeros(64, dtype=np.int64)
        self._last = np.zeros(64, dtype=np.int64)
        self._rows = np.zeros((64, width))
        self._filled = np.zeros(64, dtype=bool)
        self._child = np.full((64, width), -1, dtype=np.int64)
        self.root = self._number(root, 0, -1)

    def size(self) -> int:
        return len(self._keys)

    def _grow_labels(self) -> None:
        more = len(self.labels) - self._rows.shape[1]
        if more > 0:
            self._rows = np.hstack([self._rows, np.zeros((len(self._rows), more))])
            self._child = np.hstack([self._child, np.full((len(self._child), more), -1, dtype=np.int64)])

    def _number(self, key: Hashable, step: int, last: int) -> int:
        full = (key, step, last)
        sid = self._ids.get(full)
        if sid is None:
            sid = self._ids[full] = len(self._keys)
            self._keys.append(key)
            if sid >= len(self._step):
                grow = sid + 1
                self._step = np.concatenate([self._step, np.zeros(grow, dtype=np.int64)])
                self._last = np.concatenate([self._last, np.zeros(grow, dtype=np.int64)])
                self._rows = np.vstack([self._rows, np.zeros((grow, self._rows.shape[1]))])
                self._filled = np.concatenate([self._filled, np.zeros(grow, dtype=bool)])
                self._child = np.vstack([self._child, np.full((grow, self._child.shape[1]), -1, dtype=np.int64)])
            self._step[sid] = step
            self._last[sid] = last
        return sid

    def last(self, states: np.ndarray) -> np.ndarray:
        return self._last[states]

    def children(self, states: np.ndarray, codes: np.ndarray) -> np.ndarray:
        states, codes = np.asarray(states, dtype=np.int64), np.asarray(codes, dtype=np.int64)
        out = self._child[states, codes]
        missing = np.flatnonzero(out < 0)
        if len(missing):
            for state, code in first_met(states[missing], codes[missing], self._child.shape[1]):
                self.child(state, code)
            out[missing] = self._child[states[missing], codes[missing]]
        return out

    def child(self, state: int, code: int) -> int:
        out = int(self._child[state, code])
        if out < 0:
            step = int(self._step[state])
            key = self._advance(self._keys[state], step, self.labels[code])
            out = self._child[state, code] = self._number(key, step + 1, code)
        return out

    def rows(self, states: np.ndarray) -> np.ndarray:
        todo = np.unique(states[~self._filled[states]]) if len(states) else states
        for sid in todo.tolist():
            dist = self._dist(sid)
            codes = self.labels.indices(dist)
            if -1 in codes:  # a label the model never saw: numbered now
                codes = [self.code(a) for a in dist]
            row = self._rows[sid]
            row[:] = 0.0
            row[codes] = list(dist.values())
            self._filled[sid] = True
        return self._rows[states, : len(self.labels)]

    def _dist(self, sid: int) -> dict[str, float]:
        """The model's next-step distribution of state ``sid`` (asked once)."""
        dist = self._dists.get(sid)
        if dist is None:
            last = int(self._last[sid])
            dist = self._distribution(self._keys[sid], int(self._step[sid]))
            if not dist and last >= 0:  # a model with nothing to say: the activity stays the same
                dist = {self.labels[last]: 1.0}
            self._dists[sid] = dist
        return dist

    def distributions(self, states: np.ndarray) -> list[dict[str, float]]:
        """The model's own dicts (the rows hold the same numbers)."""
        return [dict(self._dist(sid)) for sid in np.asarray(states).tolist()]

    def scan(self, day: Sequence[str], weekday: int | None = None) -> list[dict[str, float]]:
        """The model's own dicts along ``day``, its states walked without numbering them (a scan
        visits each of its states once)."""
        out: list[dict[str, float]] = []
        key, last = self._keys[self.root], None
        for t, activity in enumerate(day):
            dist = self._distribution(key, t)
            out.append(dict(dist) if dist or last is None else {last: 1.0})
            if t + 1 < len(day):
                key, last = self._advance(key, t, activity), activity
        return out


class HistoryStates(NumberedStates):
    """The states of any object with ``predict_proba(history)``: the whole history (nothing
    merges). Test doubles and models from elsewhere go through this."""

    def __init__(self, model: Any) -> None:
        super().__init__(model, getattr(model, "classes_", ()), (), lambda h, step, a: h + (a,),
                         lambda h, step: model.predict_proba(h))


_FOREIGN: "weakref.WeakKeyDictionary[Any, StateSpace]" = weakref.WeakKeyDictionary()


def state_space(model: Any) -> StateSpace:
    """The state space of ``model`` (its own ``states()``, else a :class:`HistoryStates` over its
    ``predict_proba``), shared by every filter and forecaster over it: a fresh one once the model
    has learnt or the shared one is full. Holders of an older space keep it, so the state numbers
    they hold stay valid."""
    states = getattr(model, "states", None)
    if callable(states):
        return states()
    try:
        space = _FOREIGN.get(model)
    except TypeError:  # not weakly referenceable: a private one
        return HistoryStates(model)
    if space is None or not space.current():
        space = _FOREIGN[model] = HistoryStates(model)
    return space
