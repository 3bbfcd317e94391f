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
same order as with one dict per state. Appending keeps the further transitions of the states it
creates or changes in dicts; :meth:`compact` folds them into the table (the models call it at
the end of each fit).
"""

from __future__ import annotations

from array import array
from itertools import chain
from typing import Callable, Hashable, Iterable, Iterator, MutableSequence

import numpy as np

try:  # compiled at install where a C compiler is found (optional): the same automaton, faster
    from globe.models import _suffix_automaton as _native
except ImportError:  # pragma: no cover - depends on the install
    _native = None  # type: ignore[assignment]

END = "</s>"  # closes every training sequence; never predicted
_INT = "i"  # 32-bit signed on every platform numpy and CPython support here
assert array(_INT).itemsize == 4


class SuffixIndex:
    """Generalised suffix automaton with occurrence counts, built incrementally."""

    __slots__ = ("_ids", "_names", "_link", "_len", "_own", "_label1", "_target1", "_start", "_labels", "_targets",
                 "_more", "_last", "_counts", "_dist", "_derived", "_skip")

    def __init__(self, never_predicted: Iterable[str] = ()) -> None:
        self._skip = frozenset(never_predicted) | {END}
        self._ids: dict[str, int] = {}  # label -> its number here
        self._names: list[str] = []  # number -> label
        # Per state; lists while a fit appends (faster), typed arrays once compacted (smaller).
        self._link: MutableSequence[int] = [-1]
        self._len: MutableSequence[int] = [0]
        self._own: MutableSequence[int] = [0]  # 1 for states created as a new end position
        self._label1: MutableSequence[int] = [-1]  # the first transition: its label (-1: none) ...
        self._target1: MutableSequence[int] = [-1]  # ... and target
        # The further transitions of states 0 .. len(_start) - 2 as rows _start[s] .. _start[s + 1]
        # of (_labels, _targets), unless the state is in _more (changed, or new, since compacted).
        self._start = array(_INT, [0])
        self._labels = array(_INT)
        self._targets = array(_INT)
        self._more: dict[int, dict[int, int]] = {}
        self._last = 0
        self._counts: array | None = None
        self._dist: dict[int, dict[str, int]] = {}
        self._derived: dict[Hashable, dict[str, float]] = {}  # estimators' results, see :meth:`derived`

    # -- transitions ------------------------------------------------------------------------
    def _get(self, state: int, label: int) -> int:
        """Target of ``state`` on label number ``label``, -1 if there is none."""
        if self._label1[state] == label:
            return self._target1[state]
        more = self._more.get(state)
        if more is not None:
            return more.get(label, -1)
        if state + 1 < len(self._start):
            lo, hi = self._start[state], self._start[state + 1]
            if lo < hi:
                try:
                    return self._targets[self._labels.index(label, lo, hi)]
                except ValueError:
                    pass
        return -1

    def _rest(self, state: int) -> dict[int, int]:
        """A copy of the transitions of ``state`` after its first, in insertion order."""
        more = self._more.get(state)
        if more is not None:
            return dict(more)
        if state + 1 < len(self._start):
            lo, hi = self._start[state], self._start[state + 1]
            return dict(zip(self._labels[lo:hi], self._targets[lo:hi]))
        return {}

    def _edges(self, state: int) -> dict[int, int]:
        """A copy of the transitions of ``state`` (label number -> target), in insertion order."""
        first = self._label1[state]
        if first == -1:
            return {}
        return {first: self._target1[state], **self._rest(state)}

    def _set(self, state: int, label: int, target: int) -> None:
        """Add a transition, or redirect one (it keeps its place in the order)."""
        first = self._label1[state]
        if first == label or first == -1:
            self._label1[state] = label
            self._target1[state] = target
            return
        more = self._more.get(state)
        if more is None:
            more = self._more[state] = self._rest(state)
        more[label] = target

    # -- building ---------------------------------------------------------------------------
    def add_all(self, sequences: Iterable[Iterable[str]]) -> None:
        """:meth:`add` each of ``sequences``, then :meth:`compact` (what a fit does): in C where
        the install compiled :mod:`globe.models._suffix_automaton` (the same arrays, a tenth of
        the time or less), else in Python."""
        batch = [(*seq, END) for seq in sequences]
        if _native is None:
            for labels in batch:
                self._append(labels)
            self.compact()
        else:
            self.compact()  # the compiled loop starts from the compacted arrays
            (link, length, own, label1, target1, start, labels, targets), self._last = _native.extend(
                self._ids, self._names, self._link, self._len, self._own, self._label1, self._target1, self._start,
                self._labels, self._targets, self._last, batch)
            self._link, self._len, self._own = array(_INT, link), array(_INT, length), array("b", own)
            self._label1, self._target1 = array(_INT, label1), array(_INT, target1)
            self._start, self._labels, self._targets = array(_INT, start), array(_INT, labels), array(_INT, targets)
        self._forget_counts()

    def add(self, sequence: Iterable[str]) -> None:
        """Append one training sequence (an :data:`END` label is added after it)."""
        self._append((*sequence, END))
        self._forget_counts()

    def _forget_counts(self) -> None:
        """Drop what was derived from the counts before the last append."""
        self._counts = None
        self._dist.clear()
        self._derived.clear()

    def _append(self, labels: Iterable[str]) -> None:
        ids, names, more = self._ids, self._names, self._more
        link, length, own, label1, target1 = self._link, self._len, self._own, self._label1, self._target1
        last = self._last
        for label in labels:
            c = ids.get(label)
            if c is None:
                c = ids[label] = len(names)
                names.append(label)
            cur = len(length)
            length.append(length[last] + 1)
            link.append(0)
            own.append(1)
            label1.append(-1)
            target1.append(-1)
            p = last
            # :meth:`_get` and :meth:`_set` written out for the states that keep their further
            # transitions in a dict (every state a fit creates): this loop is the whole fit.
            while p != -1:
                first = label1[p]
                if first == c:
                    q = target1[p]
                    break
                if first == -1:  # the common case while a fit builds: a state's first transition
                    label1[p] = c
                    target1[p] = cur
                else:
                    extra = more.get(p)
                    if extra is None:
                        q = self._get(p, c)
                        if q != -1:
                            break
                        more[p] = extra = self._rest(p)
                    else:
                        q = extra.get(c, -1)
                        if q != -1:
                            break
                    extra[c] = cur
                p = link[p]
            if p != -1:
                if length[p] + 1 == length[q]:
                    link[cur] = q
                else:
                    clone = len(length)
                    length.append(length[p] + 1)
                    link.append(link[q])
                    own.append(0)
                    label1.append(label1[q])
                    target1.append(target1[q])
                    rest = self._rest(q)
                    if rest:
                        more[clone] = rest
                    while p != -1:
                        if label1[p] == c:
                            if target1[p] != q:
                                break
                            target1[p] = clone
                        else:
                            extra = more.get(p)
                            if extra is not None:
                                if extra.get(c, -1) != q:
                                    break
                                extra[c] = clone
                            elif self._get(p, c) == q:
                                self._set(p, c, clone)
                            else:
                                break
                        p = link[p]
                    link[q] = clone
                    link[cur] = clone
            last = cur
        self._last = last

    def compact(self) -> None:
        """Fold the transitions kept in dicts since the last call into the table, and the
        per-state lists into typed arrays (answers do not change, memory does: about 14 bytes per
        state instead of 250)."""
        n = len(self._len)
        if isinstance(self._len, list):
            self._len, self._link, self._own = array(_INT, self._len), array(_INT, self._link), array("b", self._own)
            self._label1, self._target1 = array(_INT, self._label1), array(_INT, self._target1)
        if not self._more and len(self._start) == n + 1:
            return
        if not self._more and len(self._start) == 1:  # never compacted, no state with a second transition
            self._start = array(_INT, [0]) * (n + 1)
            return
        start = np.frombuffer(self._start, dtype=np.int32)
        old = len(start) - 1
        owner = np.repeat(np.arange(old, dtype=np.int32), start[1:] - start[:-1])
        keep = np.ones(old + 1, dtype=bool)
        keep[[s for s in self._more if s < old]] = False
        rows = keep[owner]
        changed = sorted(self._more)
        more = [self._more[s] for s in changed]
        count = sum(map(len, more))
        owner = np.concatenate([owner[rows], np.repeat(np.asarray(changed, dtype=np.int32),
                                                       np.fromiter(map(len, more), dtype=np.int32, count=len(more)))])
        order = np.argsort(owner, kind="stable")  # by state; each state's transitions keep their order
        labels = np.concatenate([np.frombuffer(self._labels, dtype=np.int32)[rows],
                                 np.fromiter(chain.from_iterable(more), dtype=np.int32, count=count)])
        targets = np.concatenate([np.frombuffer(self._targets, dtype=np.int32)[rows],
                                  np.fromiter(chain.from_iterable(map(dict.values, more)), dtype=np.int32, count=count)])
        start = np.zeros(n + 1, dtype=np.int32)
        start[1:] = np.cumsum(np.bincount(owner, minlength=n))
        self._start = array(_INT, start.tobytes())
        self._labels = array(_INT, labels[order].tobytes())
        self._targets = array(_INT, targets[order].tobytes())
        self._more = {}

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
        if self._more or len(self._start) != len(self._len) + 1:
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
