"""Estimators over a :class:`SuffixIndex` match: pure functions from a match to a distribution.

``longest`` is the paper's rule: the longest context seen in training that has a continuation,
maximum likelihood there. ``witten_bell`` interpolates every context length (Witten & Bell
1991): P_k(w) = (c_k(w) + N1+_k * P_{k-1}(w)) / (c_k + N1+_k), down to a uniform floor.
"""

from __future__ import annotations

from typing import Literal, Mapping, Sequence

from globe.models.suffix_index import SuffixIndex

Estimator = Literal["longest", "witten_bell"]
ESTIMATORS: tuple[Estimator, ...] = ("longest", "witten_bell")


def normalise(counts: Mapping[str, float]) -> dict[str, float]:
    total = sum(counts.values())
    return {k: v / total for k, v in counts.items()} if total > 0 else {}


def longest_distribution(index: SuffixIndex, state: int, matched: int, max_context: int) -> dict[str, float]:
    """ML distribution after the longest matched context that was ever continued."""
    state, matched = index.truncate(state, matched, max_context)
    while state != -1:
        counts = index.successors(state)
        if counts:
            return normalise(counts)
        state = index.link(state)
    return {}


def witten_bell_distribution(
    index: SuffixIndex, state: int, matched: int, max_context: int, vocabulary: Sequence[str]
) -> dict[str, float]:
    """Interpolated Witten-Bell over all context lengths up to ``max_context``.

    Contexts inside one automaton state share counts, so the m lengths of a state are applied
    in closed form: P = (1 - (1-l)^m) * ML + (1-l)^m * P_lower, with l = c / (c + N1+).
    """
    if not vocabulary:
        return {}
    state, matched = index.truncate(state, matched, max_context)
    vocabulary = tuple(vocabulary)
    return index.derived(("witten_bell", state, matched, vocabulary),
                         lambda: _witten_bell(index, state, matched, vocabulary))


def _witten_bell(index: SuffixIndex, state: int, matched: int, vocabulary: tuple[str, ...]) -> dict[str, float]:
    layers = list(index.chain(state, matched))
    prob = {w: 1.0 / len(vocabulary) for w in vocabulary}
    for st, hi, lo in reversed(layers):
        m = hi - lo + 1
        counts = index.successors(st)
        total = sum(counts.values())
        if m <= 0 or total == 0:
            continue
        lam = total / (total + len(counts))
        keep = (1.0 - lam) ** m
        prob = {w: keep * p for w, p in prob.items()}
        for w, c in counts.items():
            prob[w] = prob.get(w, 0.0) + (1.0 - keep) * c / total
    return normalise(prob)
