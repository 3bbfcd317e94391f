"""A suffix automaton over training sequences: every context length at once, in linear space.

An n-gram model with maximum n = 109 would need counts for every context of up to 108 labels;
a suffix automaton stores the same information in O(total length) states. Each state groups
the contexts that occur at exactly the same training positions, so they share one
next-label distribution; its suffix link is the backoff to the next shorter context with
different statistics. Matching a history label by label is amortised O(1), so scanning a test
day yields the longest seen context at every step in linear time. Training is appending.

Storage is compact because a service keeps one automaton per model and household in memory
(tens of thousands of states each, a dict per state cost about 250 bytes): labels are numbered,
the per-state numbers live in typed arrays, and so do the transitions: each state's first one
beside it (most states have only one), the others in one flat table (compressed sparse rows),
each state's in insertion order, so every distribution comes out in the order the training
sequences first showed it. Appending is one loop in C (:mod:`globe.models._suffix_automaton`),
the only implementation of it.
"""

from __future__ import annotations

from array import array
from typing import Callable, Hashable, Iterable, Iterator

import numpy as np

from globe.models import _suffix_automaton

END = "</s>"  # closes every training sequence; never predicted
_INT = "i"  # 32-bit signed on every platform numpy and CPython support here
assert array(_INT).itemsize == 4


class SuffixIndex:
    """Generalised suffix automaton with occurrence counts, built incrementally."""

    __slots__ = ("_ids", "_names", "_link", "_len", "_own", "_label1", "_target1", "_start", "_labels", "_targets",
                 "_last", "_counts", "_dist", "_derived", "_skip")

    def __init__(self, never_predicted: Iterable[str] = ()) -> None:
        self._skip = frozenset(never_predicted) | {END}
        self._ids: dict[str, int] = {}  # label -> its number here
        self._names: list[str] = []  # number -> label
        # per state: suffix link, longest context, 1 for states created as a new end position, the
        # first transition's label (-1: none) and target; the further transitions of state s are
        # rows _start[s] .. _start[s + 1] of (_labels, _targets)
        self._link = array(_INT, [-1])
        self._len = array(_INT, [0])
        self._own = array("b", [0])
        self._label1 = array(_INT, [-1])
        self._target1 = array(_INT, [-1])
        self._start = array(_INT, [0, 0])
        self._labels = array(_INT)
        self._targets = array(_INT)
        self._last = 0
        self._counts: array | None = None
        self._dist: dict[int, dict[str, int]] = {}
        self._derived: dict[Hashable, dict[str, float]] = {}  # estimators' results, see :meth:`derived`

    # -- transitions ------------------------------------------------------------------------
    def _get(self, state: int, label: int) -> int:
        """Target of ``state`` on label number ``label``, -1 if there is none."""
        if self._label1[state] == label:
            return self._target1[state]
        lo, hi = self._start[state], self._start[state + 1]
        if lo < hi:
            try:
                return self._targets[self._labels.index(label, lo, hi)]
            except ValueError:
                pass
        return -1

    def _edges(self, state: int) -> dict[int, int]:
        """A copy of the transitions of ``state`` (label number -> target), in insertion order."""
        first = self._label1[state]
        if first == -1:
            return {}
        lo, hi = self._start[state], self._start[state + 1]
        return {first: self._target1[state], **dict(zip(self._labels[lo:hi], self._targets[lo:hi]))}

    # -- building ---------------------------------------------------------------------------
    def add_all(self, sequences: Iterable[Iterable[str]]) -> None:
        """Append each of ``sequences`` (an :data:`END` label closes each)."""
        batch = [(*seq, END) for seq in sequences]
        (link, length, own, label1, target1, start, labels, targets), self._last = _suffix_automaton.extend(
            self._ids, self._names, self._link, self._len, self._own, self._label1, self._target1, self._start,
            self._labels, self._targets, self._last, batch)
        self._link, self._len, self._own = array(_INT, link), array(_INT, length), array("b", own)
        self._label1, self._target1 = array(_INT, label1), array(_INT, target1)
        self._start, self._labels, self._targets = array(_INT, start), array(_INT, labels), array(_INT, targets)
        self._counts = None
        self._dist.clear()
        self._derived.clear()

    def __len__(self) -> int:
        """The number of states."""
        return len(self._len)

    def _occurrences(self) -> array:
        """Number of end positions of each state (= occurrences of its contexts)."""
        if self._counts is None:
            counts = array(_INT, self._own)
            length = np.array(self._len, dtype=np.int32)  # a copy: the index may grow later
            order = np.argsort(-length[1:], kind="stable") + 1  # longest first
            link = self._link
            for v in order.tolist():
                counts[link[v]] += counts[v]
            self._counts = counts
        return self._counts

    # -- querying ---------------------------------------------------------------------------
    def successors(self, state: int) -> dict[str, int]:
        """How often each label followed the contexts of ``state`` (END, start labels excluded)."""
        dist = self._dist.get(state)
        if dist is None:
            counts, names, skip = self._occurrences(), self._names, self._skip
            dist = {}
            for c, t in self._edges(state).items():
                name = names[c]
                if name not in skip:
                    dist[name] = counts[t]
            self._dist[state] = dist
        return dist

    def derived(self, key: Hashable, compute: Callable[[], dict[str, float]]) -> dict[str, float]:
        """A distribution computed from this index's counts, memoised under ``key`` until the next
        :meth:`add` (estimators are pure functions of the counts; a copy is returned)."""
        value = self._derived.get(key)
        if value is None:
            value = self._derived[key] = compute()
        return dict(value)

    def link(self, state: int) -> int:
        return self._link[state]

    def length(self, state: int) -> int:
        return self._len[state]

    def step(self, state: int, matched: int, label: str) -> tuple[int, int]:
        """Extend a match (state, matched length) by one label; unknown labels reset to root."""
        c = self._ids.get(label)
        while c is not None and state != -1:
            target = self._get(state, c)
            if target != -1:
                return target, min(matched, self._len[state]) + 1
            state = self._link[state]
        return 0, 0

    def match(self, history: Iterable[str]) -> tuple[int, int]:
        """State and length of the longest suffix of ``history`` seen in training: :meth:`step`
        over every label, with the lookup of transitions written out, as this is the inner loop
        of every prediction."""
        ids, link, length = self._ids, self._link, self._len
        label1, target1, start, labels, targets = self._label1, self._target1, self._start, self._labels, self._targets
        state, matched = 0, 0
        for label in history:
            c = ids.get(label)
            if c is None:  # never seen: nothing matches
                state, matched = 0, 0
                continue
            while state != -1:
                if label1[state] == c:  # most states have one transition
                    target = target1[state]
                else:
                    lo, hi = start[state], start[state + 1]
                    if lo == hi:
                        target = -1
                    else:
                        try:
                            target = targets[labels.index(c, lo, hi)]
                        except ValueError:
                            target = -1
                if target != -1:
                    if matched > length[state]:
                        matched = length[state]
                    state, matched = target, matched + 1
                    break
                state = link[state]
            else:
                state, matched = 0, 0
        return state, matched

    def scan(self, sequence: Iterable[str]) -> Iterator[tuple[int, int]]:
        """(state, matched) after each label of ``sequence``: every prefix in one pass."""
        state, matched = 0, 0
        for label in sequence:
            state, matched = self.step(state, matched, label)
            yield state, matched

    def truncate(self, state: int, matched: int, max_context: int) -> tuple[int, int]:
        """Shorten a match to at most ``max_context`` labels (the n-gram order limit)."""
        if matched <= max_context:
            return state, matched
        while state > 0 and self._len[self._link[state]] >= max_context:
            state = self._link[state]
        return state, max_context

    def chain(self, state: int, matched: int) -> Iterator[tuple[int, int, int]]:
        """Backoff chain from a match: (state, longest, shortest context length) down to root."""
        hi = matched
        while state != -1:
            lo = self._len[self._link[state]] + 1 if state > 0 else 0
            yield state, hi, lo
            hi = lo - 1
            state = self._link[state]
