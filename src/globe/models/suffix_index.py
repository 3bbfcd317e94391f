"""A suffix automaton over training sequences: every context length at once, in linear space.

An n-gram model with maximum n = 109 would need counts for every context of up to 108 labels;
a suffix automaton stores the same information in O(total length) states. Each state groups
the contexts that occur at exactly the same training positions, so they share one
next-label distribution; its suffix link is the backoff to the next shorter context with
different statistics. Matching a history label by label is amortised O(1), so scanning a test
day yields the longest seen context at every step in linear time. Training is appending.
"""

from __future__ import annotations

from typing import Callable, Hashable, Iterable, Iterator, Sequence

END = "</s>"  # closes every training sequence; never predicted


class SuffixIndex:
    """Generalised suffix automaton with occurrence counts, built incrementally."""

    __slots__ = ("_next", "_link", "_len", "_own", "_last", "_counts", "_dist", "_derived", "_skip")

    def __init__(self, never_predicted: Iterable[str] = ()) -> None:
        self._skip = frozenset(never_predicted) | {END}
        self._next: list[dict[str, int]] = [{}]
        self._link: list[int] = [-1]
        self._len: list[int] = [0]
        self._own: list[int] = [0]  # 1 for states created as a new end position
        self._last = 0
        self._counts: list[int] | None = None
        self._dist: dict[int, dict[str, int]] = {}
        self._derived: dict[Hashable, dict[str, float]] = {}  # estimators' results, see :meth:`derived`

    # -- building ---------------------------------------------------------------------------
    def add(self, sequence: Iterable[str]) -> None:
        """Append one training sequence (an :data:`END` label is added after it)."""
        nxt, link, length, own = self._next, self._link, self._len, self._own
        last = self._last
        for c in (*sequence, END):
            cur = len(length)
            nxt.append({})
            length.append(length[last] + 1)
            link.append(0)
            own.append(1)
            p = last
            while p != -1 and c not in nxt[p]:
                nxt[p][c] = cur
                p = link[p]
            if p != -1:
                q = nxt[p][c]
                if length[p] + 1 == length[q]:
                    link[cur] = q
                else:
                    clone = len(length)
                    nxt.append(nxt[q].copy())
                    length.append(length[p] + 1)
                    link.append(link[q])
                    own.append(0)
                    while p != -1 and nxt[p].get(c) == q:
                        nxt[p][c] = clone
                        p = link[p]
                    link[q] = clone
                    link[cur] = clone
            last = cur
        self._last = last
        self._counts = None
        self._dist.clear()
        self._derived.clear()

    def _occurrences(self) -> list[int]:
        """Number of end positions of each state (= occurrences of its contexts)."""
        if self._counts is None:
            counts = list(self._own)
            order = sorted(range(1, len(self._len)), key=self._len.__getitem__, reverse=True)
            link = self._link
            for v in order:
                counts[link[v]] += counts[v]
            self._counts = counts
        return self._counts

    # -- querying ---------------------------------------------------------------------------
    def successors(self, state: int) -> dict[str, int]:
        """How often each label followed the contexts of ``state`` (END, start labels excluded)."""
        dist = self._dist.get(state)
        if dist is None:
            counts = self._occurrences()
            dist = {c: counts[t] for c, t in self._next[state].items() if c not in self._skip}
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
        nxt, link = self._next, self._link
        while state != -1 and label not in nxt[state]:
            state = link[state]
        if state == -1:
            return 0, 0
        if matched > self._len[state]:
            matched = self._len[state]
        return nxt[state][label], matched + 1

    def match(self, history: Sequence[str]) -> tuple[int, int]:
        """State and length of the longest suffix of ``history`` seen in training."""
        state, matched = 0, 0
        for label in history:
            state, matched = self.step(state, matched, label)
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
