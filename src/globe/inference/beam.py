"""The one beam step: extend weighted histories by a model's next step, prune, renormalise.

Both users keep, per *query* (a day being filtered, or a history being forecast), a few weighted
histories of activities, and advance them one step at a time over a
:class:`~globe.models.state_space.StateSpace`:

- the activity filter **merges** extensions that reach the same state (equal states have equal
  futures, so this is exact), drops those below ``floor`` times the best one and keeps the
  ``keep`` most probable, then those at least ``floor`` of the total;
- the forecaster's path pass **keeps** every path apart, drops those below the absolute ``floor``
  (but never all: a query whose extensions are all below it keeps its most probable one), and
  keeps the ``keep`` most probable.

Ties are broken by explicit order, never by a last bit: weights are compared rounded to 30
significant bits (:func:`tie_key`), and equal ones by the history in name order (two histories
of a query are never equal), so results do not depend on the order in which sums were taken.
With no pruning (``floor = 0`` and ``keep`` large) the filter's step is the exact forward
algorithm and the path pass enumerates every path.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from globe.inference import _beam
from globe.models.state_space import StateSpace


@dataclass(frozen=True, slots=True)
class Beam:
    """Weighted histories, grouped by query (queries in increasing order).

    ``state``: each history's state in the space; ``act``: its last activity code (-1 at the
    root); ``parent``: its entry in the beam before (-1 at the root); ``lex``: its rank among its
    query's histories in name order; ``weight`` sums to 1 per query (0 for a query with none)."""

    query: np.ndarray
    weight: np.ndarray
    state: np.ndarray
    act: np.ndarray
    parent: np.ndarray
    lex: np.ndarray

    @classmethod
    def roots(cls, states: np.ndarray) -> "Beam":
        """One history per query: query q starts from ``states[q]`` with weight 1."""
        n = len(states)
        none = np.full(n, -1, dtype=np.int64)
        return cls(np.arange(n, dtype=np.int64), np.ones(n), np.asarray(states, dtype=np.int64), none, none.copy(),
                   np.zeros(n, dtype=np.int64))

    def __len__(self) -> int:
        return len(self.query)

    def totals(self, queries: int) -> np.ndarray:
        """The weight of each of ``queries`` queries (1, or 0 for a query with no history)."""
        return np.bincount(self.query, weights=self.weight, minlength=queries)


def tie_key(weights: np.ndarray) -> np.ndarray:
    """``weights`` rounded to 30 significant bits (half to even), as the beam step compares them:
    weights that differ only in the last bits of their arithmetic (sums taken in another order)
    compare equal."""
    keys = _beam.tie_key(np.ascontiguousarray(weights, dtype=np.float64))
    return np.frombuffer(keys, dtype=np.float64).reshape(np.shape(weights))


@dataclass(frozen=True, slots=True)
class Evidence:
    """What each query saw at a step, as likelihoods of the next activity given the last one:
    query q reads ``tables[table_of[q]]`` ((previous activity or none) x activity codes, the last
    row for no previous activity; at most 1)."""

    tables: np.ndarray
    table_of: np.ndarray


def advance(beam: Beam, space: StateSpace, *, merge: bool, floor: float, keep: int, rows: np.ndarray | None = None,
            evidence: Evidence | None = None, labels: np.ndarray | None = None) -> Beam:
    """The beam one step later (see module doc).

    ``rows``: the next-step rows of the beam's states, when the caller has them; ``evidence``:
    likelihoods multiplying each extension (the filter's movements seen); ``labels`` (one per
    query, -1 for none): a seen activity, which pins the step (when the model gives it no chance,
    the histories still follow it). The filter's steps (``merge``) may have both."""
    rows = space.rows(beam.state) if rows is None else rows
    nq = int(beam.query[-1]) + 1 if len(beam) else 0
    names = space.name_rank()
    if merge:
        pinned = np.full(nq, -1, dtype=np.int64) if labels is None else labels
        tables, table_of = (_NO_TABLES, _NONE) if evidence is None else (evidence.tables, evidence.table_of[beam.query])
        entry, act, w = (np.frombuffer(x, dtype=np.float64 if i == 2 else np.int64) for i, x in enumerate(
            _beam.extend(floor, nq, np.ascontiguousarray(rows), beam.weight, beam.query, pinned, tables, table_of,
                         beam.act)))
        entry, act, w = _unstick(beam, space, entry, act, w, nq, labels)
        child = space.children(beam.state[entry], act)
    else:
        if evidence is not None or labels is not None:
            raise ValueError("the path pass neither sees movements nor labels")
        entry, act, w = (np.frombuffer(x, dtype=np.float64 if i == 2 else np.int64) for i, x in enumerate(
            _beam.extend_paths(floor, nq, np.ascontiguousarray(rows), beam.weight, beam.query, beam.lex, names)))
        child = _NONE
    kept, weight, lex = (np.frombuffer(x, dtype=np.float64 if i == 1 else np.int64) for i, x in enumerate(
        _beam.select(merge, keep, floor, nq, beam.query[entry], entry, act, w, child, beam.lex, names)))
    entry, act = entry[kept], act[kept]
    state = child[kept] if merge else space.children(beam.state[entry], act)
    return Beam(beam.query[entry], weight, state, act, entry, lex)


_NONE = np.zeros(0, dtype=np.int64)
_NO_TABLES = np.zeros(0)


def _unstick(beam: Beam, space: StateSpace, entry: np.ndarray, act: np.ndarray, w: np.ndarray, nq: int,
             labels: np.ndarray | None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A query with no extension left (its label or what it saw is impossible under the model)
    keeps its histories' weights and extends them by the label, else by each one's most probable
    next activity."""
    lacking = np.bincount(beam.query[entry], minlength=nq) == 0
    if not (len(beam) and lacking[beam.query].any()):
        return entry, act, w
    stuck = np.flatnonzero(lacking[beam.query])
    guess = space.best(beam.state[stuck])
    guess = np.where(guess >= 0, guess, space.last(beam.state[stuck]))
    if labels is not None:
        pinned = labels[beam.query[stuck]]
        guess = np.where(pinned >= 0, pinned, guess)
    ok = guess >= 0
    if not ok.all() and (~ok & (beam.act[stuck] < 0)).any():
        raise ValueError("the activity model predicts nothing for the first step; is it fitted?")
    stuck, guess = stuck[ok], guess[ok]
    entry = np.concatenate([entry, stuck])
    act = np.concatenate([act, guess])
    w = np.concatenate([w, beam.weight[stuck]])
    order = np.argsort(entry, kind="stable")  # candidates in beam order, as they would have come
    return entry[order], act[order], w[order]
