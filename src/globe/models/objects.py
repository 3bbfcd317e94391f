"""Next-object model: one n-gram per activity over the objects moved in the activity run."""

from __future__ import annotations

from collections import Counter
from typing import Iterable, Sequence

from globe.models.backoff import (
    ESTIMATORS,
    longest_distribution,
    witten_bell_distribution,
)
from globe.models.base import CountingModel, rank
from globe.models.suffix_index import SuffixIndex

RUN_START = "<run>"


class ObjectModel(CountingModel):
    """P(o | a, objects moved so far in the run of a), candidates restricted to O(a).

    Trained on (activity, object sequence) pairs, one per activity run. Backs off from the
    longest matched object context down to P(o | a). With ``run_start_token`` the first object
    of a run is conditioned on the run having just begun.
    """

    _parameter_constraints = {"estimator": ESTIMATORS, "max_order": int, "run_start_token": (True, False)}
    kind = "object"
    reads_clock = False  # trained on (activity, objects) runs; the clock minute it is asked with is ignored

    def __init__(self, *, estimator: str = "longest", max_order: int = 109, run_start_token: bool = False) -> None:
        self.estimator = estimator
        self.max_order = max_order
        self.run_start_token = run_start_token

    def fit(self, runs: Iterable[tuple[str, Sequence[str]]]) -> "ObjectModel":
        """Train from scratch on (activity, objects moved in that run) pairs."""
        self._reset()
        self.__dict__.pop("_recent", None)
        return self.partial_fit(runs)

    def partial_fit(self, runs: Iterable[tuple[str, Sequence[str]]]) -> "ObjectModel":
        self.__dict__.pop("_proba", None)  # distributions over the old counts are stale
        if not hasattr(self, "training_data_"):
            self._validate_params()
            self.training_data_: list[tuple[str, tuple[str, ...]]] = []
            self.indexes_: dict[str, SuffixIndex] = {}
            self.frequency_: dict[str, Counter[str]] = {}
        added: dict[str, list[tuple[str, ...]]] = {}  # each activity's runs, in order
        for activity, objects in runs:
            objects = tuple(objects)
            self.training_data_.append((activity, objects))
            if not objects:
                continue
            mine = added.get(activity)
            if mine is None:  # not setdefault: that would build a list per run
                mine = added[activity] = []
                if activity not in self.indexes_:
                    self.indexes_[activity] = SuffixIndex(never_predicted=[RUN_START])
                    self.frequency_[activity] = Counter()
            mine.append(self._prefixed(objects))
            self.frequency_[activity].update(objects)
        for activity, mine in added.items():
            self.indexes_[activity].add_all(mine)  # compacted: typed arrays
        return self

    def _prefixed(self, objects: Sequence[str]) -> tuple[str, ...]:
        return (RUN_START, *objects) if self.run_start_token else tuple(objects)

    def recent_runs(self, activity: str, k: int) -> tuple[tuple[str, ...], ...]:
        """The last ``k`` observed runs of ``activity`` in which something moved, oldest first:
        this person's own examples, shown to the LLM."""
        self._check_fitted()
        key = (activity, k, len(self.training_data_))  # between fits runs are only added: the length dates it
        memo = self.__dict__.setdefault("_recent", {})
        out = memo.get(key)
        if out is None:
            found: list[tuple[str, ...]] = []
            for a, objects in reversed(self.training_data_):
                if len(found) == k:
                    break
                if a == activity and objects:
                    found.append(objects)
            if len(memo) > 10_000:
                memo.clear()
            out = memo[key] = tuple(reversed(found))
        return out

    def candidates(self, activity: str) -> tuple[str, ...]:
        """O(a): every object seen moving during ``activity`` in training, sorted."""
        self._check_fitted()
        return tuple(sorted(self.frequency_.get(activity, ())))

    def predict_proba(self, activity: str, history: Sequence[str] = (), minute: int | None = None
                      ) -> dict[str, float]:
        """Distribution over O(activity) of the next object, given the run's objects so far (the
        clock ``minute`` is part of the object models' interface, unread here). Memoised until the
        model learns (the protocol asks each context many times): the dict
        returned is shared, to be read and never modified."""
        self._check_fitted()
        key = (activity, tuple(history))
        memo: dict = self.__dict__.setdefault("_proba", {})
        found = memo.get(key)
        if found is None:
            index = self.indexes_.get(activity)
            if index is None:
                return {}
            state, matched = index.match(self._prefixed(history))
            if self.estimator == "longest":
                found = longest_distribution(index, state, matched, self.max_order - 1)
            else:
                found = witten_bell_distribution(index, state, matched, self.max_order - 1,
                                                 self.candidates(activity))
            if len(memo) > 100_000:
                memo.clear()
            memo[key] = found
        return found

    def ranked(self, activity: str, distribution: dict[str, float]) -> list[str]:
        return rank(distribution, self.frequency_.get(activity, {}))

    def predict(self, activity: str, history: Sequence[str] = ()) -> str | None:
        ranked = self.ranked(activity, self.predict_proba(activity, history))
        return ranked[0] if ranked else None

    def confidence(self, activity: str, history: Sequence[str] = ()) -> float:
        """The top probability: below the gate's threshold d the LLM is consulted."""
        return max(self.predict_proba(activity, history).values(), default=0.0)
