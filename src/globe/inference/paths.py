"""The forward pass over activity *paths*: what the person may do at each of the next steps.

From each query's state (the day so far) the paths are extended by the activity model's own
next-step distribution (:func:`globe.inference.beam.advance` keeping every path apart), paths
below ``min_path_probability`` are pruned, at most ``max_paths`` are kept per query and the
beam is renormalised; with no pruning this is the exact distribution over paths. The kept paths
are then laid out as prefix trees, level by level, with what a movement hazard reads at each
node (the activity left, how long its run had lasted, whether it ends there), for the forecaster.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from globe.inference.beam import Beam, advance, tie_key
from globe.models.state_space import StateSpace, state_space
from globe.models.vocabulary import Vocabulary


@dataclass(frozen=True, slots=True)
class Roots:
    """Where each query's paths start: the state after a_0..a_{m-1} (``state``, in ``space``),
    a_{m-1} and how many steps its run had lasted before m-1 (``prev``, ``duration``; -1 when
    m = 0), and a_m when it is known (``head``: then the paths start one step later)."""

    space: StateSpace
    state: np.ndarray
    prev: np.ndarray
    duration: np.ndarray
    head: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.state)


@dataclass(frozen=True, slots=True)
class TreeLevel:
    """The activities at step m + i of every kept prefix of every query (nodes grouped by query,
    in the order the query's paths, most likely first, first name them). Each node carries what
    the hazard of the step into it reads: its parent node, the parent's activity (``up``), how
    long the parent's run had lasted (``dur_up``), whether the parent's run is the one under way
    at m-1 (``first_up``) and whether the run ends (``ends``); ``group`` numbers the distinct
    (query, parent activity) in the order they first appear (``group_query``, ``group_act``)."""

    query: np.ndarray
    act: np.ndarray
    weight: np.ndarray
    dur: np.ndarray
    first: np.ndarray
    parent: np.ndarray
    up: np.ndarray
    dur_up: np.ndarray
    first_up: np.ndarray
    ends: np.ndarray
    group: np.ndarray
    group_query: np.ndarray
    group_act: np.ndarray


@dataclass(frozen=True, slots=True)
class TreeBatch:
    """The weighted activity prefixes of several forecasts (levels i = 0..horizon+1); activity
    codes are those of ``names``."""

    size: int
    horizon: int
    levels: tuple[TreeLevel, ...]
    names: Vocabulary

    def activity(self, q: int) -> tuple[dict[str, float], ...]:
        """P(activity at m + k) for k = 0..horizon of query ``q``."""
        out: list[dict[str, float]] = []
        names = self.names
        for level in self.levels[: self.horizon + 1]:
            lo, hi = np.searchsorted(level.query, [q, q + 1])
            acts = level.act[lo:hi]
            sums = np.bincount(acts, weights=level.weight[lo:hi]).tolist()  # summed in entry order, as one by one
            out.append({names[a]: sums[a] for a in dict.fromkeys(acts.tolist())})  # in the order first seen
        return tuple(out)

    def activity_matrix(self) -> np.ndarray:
        """(queries x horizon+1 x names): the same distributions, dense."""
        width = len(self.names)
        out = np.zeros((self.size, self.horizon + 1, width))
        for k, level in enumerate(self.levels[: self.horizon + 1]):
            out[:, k] = np.bincount(level.query * width + level.act, weights=level.weight,
                                    minlength=self.size * width).reshape(self.size, width)
        return out


SMALL = 160
"""Below this many keys a dict finds the first-seen order faster than sorting them (a session's
forecast asks for it at every level of every step, each time over a few dozen paths)."""


def _first_seen(keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(the distinct keys in the order they first appear, each element's index into them)."""
    if keys.ndim == 1 and len(keys) <= SMALL:
        index: dict[int, int] = {}
        where = [index.setdefault(k, len(index)) for k in keys.tolist()]
        return np.array(list(index), dtype=keys.dtype), np.array(where, dtype=np.int64)
    uniq, first, inverse = np.unique(keys, return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")
    rank = np.empty(len(uniq), dtype=np.int64)
    rank[order] = np.arange(len(uniq))
    return uniq[order], rank[inverse.reshape(-1)]


class ActivityPaths:
    """The forward pass over one fitted activity model's paths (see module doc). Its memos are
    the model's state space, shared with every filter and forecaster over the model."""

    def __init__(self, model: Any, *, min_path_probability: float = 1e-3, max_paths: int = 64) -> None:
        self.model = model
        self.min_path_probability = min_path_probability
        self.max_paths = max_paths
        self.space: StateSpace = state_space(model)

    def _current(self) -> StateSpace:
        """The model's state space (a fresh one once the model has learnt)."""
        if not self.space.current():
            self.space = state_space(self.model)
        return self.space

    def roots(self, histories: Sequence[Sequence[str]], starts: Sequence[int],
              weekdays: Sequence[int | None] | None = None) -> Roots:
        """The roots of queries given as histories a_0..a_{n-1} whose last known places are at
        step m = ``starts[q]`` (n = m, or n = m + 1 when a_m is known: the same for all), on days
        of ``weekdays`` (Monday 0; None: not known)."""
        space = self._current()
        heads = {len(h) - m for h, m in zip(histories, starts)}
        if len(heads) > 1 or not heads <= {0, 1}:
            raise ValueError("every history of a batch must end at m - 1 or every one at m")
        head = heads.pop() if heads else 0
        nq = len(histories)
        prev = np.full(nq, -1, dtype=np.int64)
        duration = np.full(nq, -1, dtype=np.int64)
        for q, (h, m) in enumerate(zip(histories, starts)):
            if 1 <= m <= len(h):
                a, d = h[m - 1], 0
                while d < m - 1 and h[m - 2 - d] == a:
                    d += 1
                prev[q], duration[q] = space.code(a), d
        days = [None] * nq if weekdays is None else weekdays
        if len(days) != nq:
            raise ValueError(f"{len(days)} days of the week for {nq} histories")
        states = np.array([space.state(h, w) for h, w in zip(histories, days)], dtype=np.int64)
        heads_ = np.array([space.code(h[m]) for h, m in zip(histories, starts)], dtype=np.int64) if head else None
        return Roots(space, states, prev, duration, heads_)

    def forward(self, states: np.ndarray, steps: int, space: StateSpace | None = None) -> list[Beam]:
        """The kept paths after 1..``steps`` steps from each of ``states`` (of ``space``, by default
        the model's current one)."""
        space = self._current() if space is None else space
        beam = Beam.roots(np.asarray(states, dtype=np.int64))
        levels = []
        for _ in range(steps):
            beam = advance(beam, space, merge=False, floor=self.min_path_probability, keep=self.max_paths)
            levels.append(beam)
        return levels

    def paths(self, history: Sequence[str], steps: int,
              weekday: int | None = None) -> list[tuple[float, tuple[str, ...]]]:
        """The next ``steps`` activities after ``history`` (on a day of ``weekday``, when known):
        (probability, path), most likely first."""
        space = self._current()
        levels = self.forward(np.array([space.state(history, weekday)]), steps)
        if not levels or not len(levels[-1]):
            return []
        out = []
        for e in range(len(levels[-1])):
            path, i = [], e
            for level in reversed(levels):
                path.append(space.labels[int(level.act[i])])
                i = int(level.parent[i])
            out.append((float(levels[-1].weight[e]), tuple(reversed(path))))
        return sorted(out, key=lambda item: (-item[0], item[1]))

    def trees(self, roots: Roots, horizon: int) -> TreeBatch:
        """The prefix trees of the activities at steps m..m+horizon+1 from each root, weighted by
        the final paths."""
        space = roots.space
        if space.model is not self.model:
            raise ValueError("the roots are states of another model")
        nq = len(roots)
        head = roots.head is not None
        beams = self.forward(roots.state, horizon + 2 - int(head), space)
        final = beams[-1] if beams else Beam.roots(np.zeros(0, dtype=np.int64))
        order = np.lexsort((final.lex, -tie_key(final.weight), final.query))  # each query's paths, most likely first
        fq, fw = final.query[order], final.weight[order]
        dead = np.bincount(fq, minlength=nq) == 0  # the model predicts nothing: one empty path
        anc = [order]
        for t in range(len(beams) - 1, 0, -1):
            anc.append(beams[t].parent[anc[-1]])
        anc.reverse()  # anc[t-1]: the entry of beam level t each sorted final path goes through
        levels: list[TreeLevel] = []
        up_act, up_dur, up_first = roots.prev, roots.duration, np.ones(nq, dtype=bool)
        up_node_of: np.ndarray | None = None  # entry of the beam level before -> node index
        width = len(space.labels)
        for i in range(horizon + 2):
            if head and i == 0:
                assert roots.head is not None
                query, act = np.arange(nq), roots.head
                weight = np.bincount(fq, weights=fw, minlength=nq)
                weight[dead] = 1.0
                parent = np.arange(nq)
                node_of_entry = None
            else:
                t = i + 1 - int(head)
                if t > len(anc):
                    break
                entries, node_of_path = _first_seen(anc[t - 1])
                query, act = beams[t - 1].query[entries], beams[t - 1].act[entries]
                weight = np.bincount(node_of_path, weights=fw, minlength=len(entries))
                node_of_entry = np.full(len(beams[t - 1]), -1, dtype=np.int64)
                node_of_entry[entries] = np.arange(len(entries))
                if i == 0 or up_node_of is None:  # the level before is the root or the known head
                    parent = query.copy()
                else:
                    parent = up_node_of[beams[t - 1].parent[entries]]
            if not len(query):
                break
            up, dur_up, first_up = up_act[parent], up_dur[parent], up_first[parent]
            same = act == up
            dur = np.where(same, dur_up + 1, 0)
            first = first_up & same
            keys = query * (width + 1) + up + 1
            gkeys, group = _first_seen(keys)
            levels.append(TreeLevel(query, act, weight, dur, first, parent, up, dur_up, first_up, ~same, group,
                                    gkeys // (width + 1), gkeys % (width + 1) - 1))
            up_act, up_dur, up_first, up_node_of = act, dur, first, node_of_entry
        return TreeBatch(nq, horizon, tuple(levels), space.labels)


def known_trees(histories: Sequence[Sequence[str]], starts: Sequence[int], futures: Sequence[Sequence[str]],
                horizon: int) -> tuple[TreeBatch, Roots]:
    """One path of weight 1 per query: the activities ``futures[q]`` at steps m..m+horizon+1
    (m = ``starts[q]``; one short of that is padded with its last activity). What the forecaster
    is told by an *oracle* that knows the true activity ahead, laid out as :meth:`ActivityPaths.trees`
    lays out a model's paths (codes of a vocabulary of the labels named; ``roots`` carries the
    run under way at m-1 as :meth:`ActivityPaths.roots` does, without a model's state)."""
    nq = len(histories)
    names = Vocabulary(sorted({a for h in histories for a in h} | {a for f in futures for a in f}))
    prev = np.full(nq, -1, dtype=np.int64)
    duration = np.full(nq, -1, dtype=np.int64)
    path = np.zeros((nq, horizon + 2), dtype=np.int64)
    for q, (h, m, future) in enumerate(zip(histories, starts, futures)):
        if not future:
            raise ValueError(f"query {q}: no activity ahead to follow")
        if 1 <= m <= len(h):
            a, d = h[m - 1], 0
            while d < m - 1 and h[m - 2 - d] == a:
                d += 1
            prev[q], duration[q] = names.index(a), d
        codes = names.indices(future[: horizon + 2])
        path[q] = codes + [codes[-1]] * (horizon + 2 - len(codes))
    heads = np.array([names.index(h[m]) if len(h) > m else -1 for h, m in zip(histories, starts)], dtype=np.int64)
    query, ones, same_query = np.arange(nq), np.ones(nq), np.arange(nq)
    levels: list[TreeLevel] = []
    up, dur_up, first_up = prev, duration, np.ones(nq, dtype=bool)
    for i in range(horizon + 2 if nq else 0):
        act = path[:, i]
        same = act == up
        dur = np.where(same, dur_up + 1, 0)
        first = first_up & same
        levels.append(TreeLevel(query, act, ones, dur, first, same_query, up, dur_up, first_up, ~same, same_query,
                                query, up.copy()))
        up, dur_up, first_up = act, dur, first
    batch = TreeBatch(nq, horizon, tuple(levels), names)
    return batch, Roots(_NO_SPACE, np.zeros(nq, dtype=np.int64), prev, duration,
                        heads if nq and (heads >= 0).all() else None)


_NO_SPACE: Any = None  # the roots of known paths belong to no model's state space
