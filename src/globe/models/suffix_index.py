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
beside it (most states have only one), the others in one flat table (compressed sparse rows).
Every state keeps its transitions in insertion order, so each distribution comes out in the
same order as with one dict per state. Appending works on dicts: for the states it creates, and
for the states it changes; :meth:`compact` folds them back into the arrays (the models call it
at the end of each fit).
"""

from __future__ import annotations

from array import array
from itertools import chain
from typing import Callable, Hashable, Iterable, Iterator, MutableSequence

import numpy as np

END = "</s>"  # closes every training sequence; never predicted
_INT = "i"  # 32-bit signed on every platform numpy and CPython support here
assert array(_INT).itemsize == 4


class SuffixIndex:
    """Generalised suffix automaton with occurrence counts, built incrementally."""

    __slots__ = ("_ids", "_names", "_link", "_len", "_own", "_label1", "_target1", "_start", "_labels", "_targets",
                 "_tail", "_thawed", "_last", "_counts", "_dist", "_derived", "_skip")

    def __init__(self, never_predicted: Iterable[str] = ()) -> None:
        self._skip = frozenset(never_predicted) | {END}
        self._ids: dict[str, int] = {}  # label -> its number here
        self._names: list[str] = []  # number -> label
        # lists while a fit appends (faster), typed arrays once compacted (smaller)
        self._link: MutableSequence[int] = [-1]
        self._len: MutableSequence[int] = [0]
        self._own: MutableSequence[int] = [0]  # 1 for states created as a new end position
        # Transitions of the compacted states 0 .. F-1 (F = len(_label1)): the first one
        # (label -1: none), then rows _start[s] .. _start[s+1] of (_labels, _targets).
        self._label1 = array(_INT)
        self._target1 = array(_INT)
        self._start = array(_INT, [0])
        self._labels = array(_INT)
        self._targets = array(_INT)
        self._tail: list[dict[int, int]] = [{}]  # transitions of states F.. (created since the last compact)
        self._thawed: dict[int, dict[int, int]] = {}  # compacted states changed since then
        self._last = 0
        self._counts: array | None = None
        self._dist: dict[int, dict[str, int]] = {}
        self._derived: dict[Hashable, dict[str, float]] = {}  # estimators' results, see :meth:`derived`

    # -- transitions ------------------------------------------------------------------------
    def _get(self, state: int, label: int) -> int:
        """Target of ``state`` on label number ``label``, -1 if there is none."""
        frozen = len(self._label1)
        if state >= frozen:
            return self._tail[state - frozen].get(label, -1)
        edges = self._thawed.get(state)
        if edges is not None:
            return edges.get(label, -1)
        if self._label1[state] == label:
            return self._target1[state]
        lo, hi = self._start[state], self._start[state + 1]
        if lo == hi:
            return -1
        try:
            return self._targets[self._labels.index(label, lo, hi)]
        except ValueError:
            return -1

    def _edges(self, state: int) -> dict[int, int]:
        """A copy of the transitions of ``state`` (label number -> target), in insertion order."""
        frozen = len(self._label1)
        if state >= frozen:
            return dict(self._tail[state - frozen])
        edges = self._thawed.get(state)
        if edges is not None:
            return dict(edges)
        first = self._label1[state]
        out = {} if first == -1 else {first: self._target1[state]}
        lo, hi = self._start[state], self._start[state + 1]
        out.update(zip(self._labels[lo:hi], self._targets[lo:hi]))
        return out

    def _editable(self, state: int) -> dict[int, int]:
        """The transitions of ``state`` as a dict that may be changed (folded in by :meth:`compact`)."""
        frozen = len(self._label1)
        if state >= frozen:
            return self._tail[state - frozen]
        edges = self._thawed.get(state)
        if edges is None:
            edges = self._thawed[state] = self._edges(state)
        return edges

    # -- building ---------------------------------------------------------------------------
    def add(self, sequence: Iterable[str]) -> None:
        """Append one training sequence (an :data:`END` label is added after it)."""
        ids, names, tail = self._ids, self._names, self._tail
        link, length, own = self._link, self._len, self._own
        frozen = len(self._label1)
        last = self._last
        for label in (*sequence, END):
            c = ids.get(label)
            if c is None:
                c = ids[label] = len(names)
                names.append(label)
            cur = len(length)
            tail.append({})
            length.append(length[last] + 1)
            link.append(0)
            own.append(1)
            p = last
            while p != -1:
                if p >= frozen:  # the common case while a fit builds: a plain dict
                    edges = tail[p - frozen]
                    q = edges.get(c, -1)
                else:
                    q = self._get(p, c)
                    edges = self._editable(p) if q == -1 else {}
                if q != -1:
                    break
                edges[c] = cur
                p = link[p]
            if p != -1:
                if length[p] + 1 == length[q]:
                    link[cur] = q
                else:
                    clone = len(length)
                    tail.append(dict(tail[q - frozen]) if q >= frozen else self._edges(q))
                    length.append(length[p] + 1)
                    link.append(link[q])
                    own.append(0)
                    while p != -1:
                        if p >= frozen:
                            edges = tail[p - frozen]
                            if edges.get(c) != q:
                                break
                        elif self._get(p, c) == q:
                            edges = self._editable(p)
                        else:
                            break
                        edges[c] = clone
                        p = link[p]
                    link[q] = clone
                    link[cur] = clone
            last = cur
        self._last = last
        self._counts = None
        self._dist.clear()
        self._derived.clear()

    def compact(self) -> None:
        """Fold the states created or changed since the last call into the arrays (answers do
        not change, memory does: about 14 bytes per state instead of 250)."""
        if len(self._tail) == 0 and not self._thawed:
            return
        frozen, n = len(self._label1), len(self._len)
        label1 = np.frombuffer(self._label1, dtype=np.int32)
        has_first = np.flatnonzero(label1 >= 0)
        start = np.frombuffer(self._start, dtype=np.int32)
        rest_owner = np.repeat(np.arange(frozen, dtype=np.int32), start[1:] - start[:-1])
        owner = np.concatenate([has_first.astype(np.int32), rest_owner])  # first transitions before the others
        labels = np.concatenate([label1[has_first], np.frombuffer(self._labels, dtype=np.int32)])
        targets = np.concatenate([np.frombuffer(self._target1, dtype=np.int32)[has_first],
                                  np.frombuffer(self._targets, dtype=np.int32)])
        keep = np.ones(frozen, dtype=bool)
        keep[np.fromiter(self._thawed, dtype=np.int32, count=len(self._thawed))] = False
        rows = keep[owner]
        changed = sorted(self._thawed)
        edges = [self._thawed[s] for s in changed] + self._tail
        states = np.concatenate([np.asarray(changed, dtype=np.int32), np.arange(frozen, n, dtype=np.int32)])
        new_owner = np.repeat(states, np.fromiter(map(len, edges), dtype=np.int32, count=len(edges)))
        count = len(new_owner)
        owner = np.concatenate([owner[rows], new_owner])
        order = np.argsort(owner, kind="stable")  # by state; each state's transitions keep their order
        owner = owner[order]
        labels = np.concatenate([labels[rows], np.fromiter(chain.from_iterable(edges), dtype=np.int32, count=count)])[order]
        targets = np.concatenate([targets[rows], np.fromiter(chain.from_iterable(map(dict.values, edges)),
                                                             dtype=np.int32, count=count)])[order]
        first = np.ones(len(owner), dtype=bool)
        first[1:] = owner[1:] != owner[:-1]
        label1 = np.full(n, -1, dtype=np.int32)
        target1 = np.full(n, -1, dtype=np.int32)
        label1[owner[first]] = labels[first]
        target1[owner[first]] = targets[first]
        start = np.zeros(n + 1, dtype=np.int32)
        start[1:] = np.cumsum(np.bincount(owner[~first], minlength=n))
        self._label1, self._target1 = array(_INT, label1.tobytes()), array(_INT, target1.tobytes())
        self._start = array(_INT, start.tobytes())
        self._labels, self._targets = array(_INT, labels[~first].tobytes()), array(_INT, targets[~first].tobytes())
        self._tail, self._thawed = [], {}
        if isinstance(self._len, list):
            self._len, self._link, self._own = array(_INT, self._len), array(_INT, self._link), array("b", self._own)

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
        over every label, with the lookup of compacted transitions (:meth:`_get`) written out,
        as this is the inner loop of every prediction."""
        if self._tail or self._thawed:
            state, matched = 0, 0
            for label in history:
                state, matched = self.step(state, matched, label)
            return state, matched
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
