"""What the activity will be further ahead, from the activity model alone: the marginal of the
activity 1..k steps after a state, and the first activity *different* from the current one.

Both walk the model's state space with the filter's beam step (histories with equal states
merged, so a Markov state space is followed exactly up to ``keep`` states per query). The
forecaster's path pass keeps paths apart for the movement hazards; these questions need only the
states, which is cheaper and, for the long horizons of a fine step, exact.
"""

from __future__ import annotations

import numpy as np

from globe.inference.beam import Beam, advance
from globe.models.state_space import StateSpace

FLOOR = 1e-6
"""Histories below this weight are dropped (their mass is spread over the rest)."""
KEEP = 256
"""Most states kept per query and step."""


def activity_marginals(space: StateSpace, states: np.ndarray, steps: int, *, floor: float = FLOOR,
                       keep: int = KEEP) -> np.ndarray:
    """(queries x steps x labels): P(the activity j steps after each of ``states``), j = 1..steps
    (columns: ``space.labels`` as they are when called)."""
    nq, width = len(states), len(space.labels)
    out = np.zeros((nq, steps, width))
    beam = Beam.roots(np.asarray(states, dtype=np.int64))
    for j in range(steps):
        if not len(beam):
            break
        beam = advance(beam, space, merge=True, floor=floor, keep=keep)
        cells = np.bincount(beam.query * width + beam.act, weights=beam.weight, minlength=nq * width)
        out[:, j] = cells[: nq * width].reshape(nq, width)
    return out


def next_different(space: StateSpace, states: np.ndarray, current: np.ndarray, limits: np.ndarray, *,
                   floor: float = FLOOR, keep: int = KEEP) -> np.ndarray:
    """(queries x labels): P(the first activity after each of ``states`` that differs from
    ``current`` (codes) is each label, within ``limits`` steps). Rows may sum to less than 1:
    the rest is the chance that nothing changes in time."""
    nq, width = len(states), len(space.labels)
    current = np.asarray(current, dtype=np.int64)
    limits = np.asarray(limits, dtype=np.int64)
    out = np.zeros((nq, width))
    scale = np.ones(nq)  # the mass of each query's histories that have not changed yet
    beam = Beam.roots(np.asarray(states, dtype=np.int64))
    step = 0
    while len(beam):
        step += 1
        beam = advance(beam, space, merge=True, floor=floor, keep=keep)
        mass = beam.weight * scale[beam.query]
        changed = beam.act != current[beam.query]
        np.add.at(out, (beam.query[changed], beam.act[changed]), mass[changed])
        stay = ~changed & (limits[beam.query] > step)
        scale = np.bincount(beam.query[stay], weights=mass[stay], minlength=nq).astype(float)
        n = int(stay.sum())
        beam = Beam(beam.query[stay], beam.weight[stay], beam.state[stay], beam.act[stay],
                    np.full(n, -1, dtype=np.int64), beam.lex[stay])
    return out
