"""What both counting models share: scikit-learn-style parameters, fitted checks, ranking."""

from __future__ import annotations

import copy
import itertools
from collections import Counter
from typing import TYPE_CHECKING, Any, ClassVar, Mapping, Optional, Sequence

import numpy as np

from globe.errors import ConfigError, NotFittedError

Weekdays = Optional[Sequence[Optional[int]]]
"""Each training day's day of the week (Monday 0; None: not known), or None for no dates at all."""

if TYPE_CHECKING:
    from globe.models.state_space import StateSpace


def check_is_fitted(model: Any) -> None:
    """Raise :class:`NotFittedError` unless ``model`` (any estimator here) has been fitted, as
    scikit-learn's function of that name does."""
    if not hasattr(model, "training_data_"):
        raise NotFittedError(f"this {type(model).__name__} is not fitted yet; call fit() with training data first")


class CountingModel:
    """Base of the n-gram models. Constructors only store keyword parameters; ``fit`` is
    "reset, then one ``partial_fit``", so batch and incremental training cannot drift apart."""

    _parameter_constraints: ClassVar[dict[str, tuple[Any, ...] | type]] = {}
    _optional_params: ClassVar[frozenset[str]] = frozenset()
    """Parameters that may also be None (a value derived from the training data)."""
    _prediction_params: ClassVar[frozenset[str]] = frozenset()
    """Parameters read only when predicting: models that differ only in these count the same."""
    kind: ClassVar[str] = ""

    def get_params(self) -> dict[str, Any]:
        return {name: getattr(self, name) for name in self._parameter_constraints}

    def fit_params(self) -> dict[str, Any]:
        """The parameters that change what :meth:`fit` counts."""
        return {k: v for k, v in self.get_params().items() if k not in self._prediction_params}

    def prediction_params(self) -> dict[str, Any]:
        """The parameters read only when predicting (what :meth:`with_prediction_params` sets)."""
        return {k: v for k, v in self.get_params().items() if k in self._prediction_params}

    def with_prediction_params(self, **params: Any) -> "CountingModel":
        """A fitted copy answering with other prediction-only parameters. It *shares* this model's
        counts (cross-validation fits each fold once for every such candidate), so it must not
        learn more days: only the original may."""
        self._check_fitted()
        bad = set(params) - self._prediction_params
        if bad:
            raise ValueError(f"{type(self).__name__}: {sorted(bad)} change what is counted; fit a new model instead")
        clone = copy.copy(self)
        for name, value in params.items():
            setattr(clone, name, value)
        clone._validate_params()
        clone._forget()  # its memos answer with its own parameters
        return clone

    def _forget(self) -> None:
        """Drop what was derived from the counts and the parameters (a model's memos)."""

    def _validate_params(self) -> None:
        for name, allowed in self._parameter_constraints.items():
            value = getattr(self, name)
            if value is None and name in self._optional_params:
                continue
            if isinstance(allowed, tuple):
                if value not in allowed:
                    raise ConfigError(
                        f"{type(self).__name__}: {name}={value!r}; expected one of {', '.join(map(repr, allowed))}"
                    )
            elif allowed is int and (not isinstance(value, int) or value < 1):
                raise ConfigError(f"{type(self).__name__}: {name}={value!r}; expected a positive integer")
            elif allowed is float and (not isinstance(value, (int, float)) or value < 0):
                raise ConfigError(f"{type(self).__name__}: {name}={value!r}; expected a number >= 0")

    def _check_fitted(self) -> None:
        check_is_fitted(self)

    def _reset(self) -> None:
        for name in [n for n in vars(self) if n.endswith("_") and not n.startswith("_")]:
            delattr(self, name)

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self.get_params().items())
        return f"{type(self).__name__}({args})"


def windowed_prior(by_step: Sequence[Mapping[str, int]], step: int, window: int,
                   classes: Sequence[str]) -> dict[str, float]:
    """P(a | step): counts pooled over ``step`` +- ``window``, add-one smoothed over ``classes``."""
    counts: Counter[str] = Counter()
    for t in range(max(0, step - window), min(len(by_step), step + window + 1)):
        counts.update(by_step[t])
    total = sum(counts.values()) + len(classes)
    return {a: (counts.get(a, 0) + 1) / total for a in classes}


def rank(distribution: Mapping[str, float], frequency: Mapping[str, int]) -> list[str]:
    """Labels by probability; ties by training frequency, then by label (deterministic)."""
    return sorted(distribution, key=lambda w: (-distribution[w], -frequency.get(w, 0), str(w)))


def top(distribution: Mapping[str, float], frequency: Mapping[str, int]) -> str | None:
    """``rank(distribution, frequency)[0]`` without sorting everything (None if empty)."""
    if not distribution:
        return None
    best = max(distribution.values())
    tied = [w for w, p in distribution.items() if p == best]
    return tied[0] if len(tied) == 1 else min(tied, key=lambda w: (-frequency.get(w, 0), str(w)))


def stay_or_change(best: str | None, distribution: Mapping[str, float], current: str | None,
                   stay_margin: float) -> str | None:
    """The next activity said: ``best`` (the likeliest), unless it is a change and not at least
    ``stay_margin`` times as probable as ``current`` staying. A probability model is chosen by log
    loss; this point decision by what it is scored on (weighted F1), so a home where changes are
    hard to time is told "it stays" rather than a change that is right a third of the time."""
    if best is None or current is None or best == current or stay_margin <= 1.0:
        return best
    return current if distribution.get(best, 0.0) < stay_margin * distribution.get(current, 0.0) else best


class ActivityModelBase(CountingModel):
    """What every next-activity model shares: fit = reset + partial_fit, ranking, argmax,
    confidence, and ``predict_proba`` / ``scan_proba`` written once over the model's integer state
    space (:mod:`globe.models.state_space`), the one hook each model implements (``_build_states``)."""

    frequency_: Counter
    classes_: tuple[str, ...]
    fit_version_: int
    _priors: tuple[int, dict[tuple[int, int], dict[str, float]]] | None = None
    _space: Any = None

    def fit(self, days: Sequence[Sequence[str]], weekdays: Weekdays = None):
        """Train from scratch on per-day activity sequences (``weekdays``: each day's day of the
        week, Monday 0, or None; only models that know the day of the week read it)."""
        self._reset()
        return self.partial_fit(days, weekdays)

    def partial_fit(self, days: Sequence[Sequence[str]],
                    weekdays: Weekdays = None):  # pragma: no cover - abstract
        raise NotImplementedError

    def _learnt(self) -> None:
        """Called at the end of every ``partial_fit``: memos over the old counts are stale."""
        self.fit_version_ = _next_version()
        self._forget()

    def _forget(self) -> None:
        self._priors = None
        self._space = None

    # -- the hook ---------------------------------------------------------------------------
    def _build_states(self) -> "StateSpace":
        """A fresh state space of this fitted model: each model builds its own; a subclass that
        only overrides ``predict_proba`` (a test double) gets one whose state is the whole history."""
        if type(self).predict_proba is ActivityModelBase.predict_proba:
            raise NotImplementedError(f"{type(self).__name__} implements neither _build_states nor predict_proba")
        from globe.models.state_space import HistoryStates

        return HistoryStates(self)

    def states(self) -> "StateSpace":
        """This model's state space, shared by every filter and forecaster over it (a fresh one
        once it is full: holders of the old one keep it)."""
        self._check_fitted()
        space = self._space
        if space is None or not space.current():
            space = self._space = self._build_states()
        return space

    # -- prediction, once for every model ---------------------------------------------------------
    def predict_proba(self, history: Sequence[str], weekday: int | None = None) -> dict[str, float]:
        """P(the next activity | ``history``, the day so far from its first step, and the day of
        the week when known: Monday 0)."""
        space = self.states()
        return space.distributions(np.array([space.state(history, weekday)]))[0]

    def scan_proba(self, day: Sequence[str], weekday: int | None = None) -> list[dict[str, float]]:
        """``[predict_proba(day[:t], weekday) for t in range(len(day))]`` in one pass."""
        return self.states().scan(day, weekday)

    def ranked(self, distribution: Mapping[str, float]) -> list[str]:
        return rank(distribution, self.frequency_)

    def top(self, distribution: Mapping[str, float]) -> str | None:
        """The first of :meth:`ranked` (None if the distribution is empty)."""
        return top(distribution, self.frequency_)

    def _reset(self) -> None:
        super()._reset()
        self._priors = None

    def step_prior(self, by_step: Sequence[Mapping[str, int]], step: int, window: int) -> dict[str, float]:
        """:func:`windowed_prior` over ``classes_``, memoised per step until days are added (every
        scan of every cross-validation fold asks it again at each step)."""
        version = getattr(self, "fit_version_", 0)
        if self._priors is None or self._priors[0] != version:
            self._priors = (version, {})
        memo = self._priors[1]
        prior = memo.get((step, window))
        if prior is None:
            prior = memo[(step, window)] = windowed_prior(by_step, step, window, self.classes_)
        return prior

    def predict(self, history: Sequence[str], weekday: int | None = None) -> str | None:
        """Most probable next activity (ties: training frequency, then name)."""
        ranked = self.ranked(self.predict_proba(history, weekday))
        return ranked[0] if ranked else None

    def confidence(self, history: Sequence[str], weekday: int | None = None) -> float:
        """The top probability: what the gate and the robot's action threshold look at."""
        return max(self.predict_proba(history, weekday).values(), default=0.0)


_VERSIONS = itertools.count(1)


def _next_version() -> int:
    """A number no model has had: a model's ``fit_version_`` after each fit or partial fit."""
    return next(_VERSIONS)
