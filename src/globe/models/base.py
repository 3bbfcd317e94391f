"""What both counting models share: scikit-learn-style parameters, fitted checks, ranking."""

from __future__ import annotations

from collections import Counter
from typing import Any, ClassVar, Mapping, Sequence

from globe.errors import ConfigError, NotFittedError


class CountingModel:
    """Base of the n-gram models. Constructors only store keyword parameters; ``fit`` is
    "reset, then one ``partial_fit``", so batch and incremental training cannot drift apart."""

    _parameter_constraints: ClassVar[dict[str, tuple[Any, ...] | type]] = {}
    kind: ClassVar[str] = ""

    def get_params(self) -> dict[str, Any]:
        return {name: getattr(self, name) for name in self._parameter_constraints}

    def _validate_params(self) -> None:
        for name, allowed in self._parameter_constraints.items():
            value = getattr(self, name)
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
        if not hasattr(self, "training_data_"):
            raise NotFittedError(
                f"this {type(self).__name__} is not fitted yet; call fit() with training data first"
            )

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


class ActivityModelBase(CountingModel):
    """What every next-activity model shares: fit = reset + partial_fit, ranking, argmax,
    confidence, and a default prefix scan (subclasses override it with a linear pass)."""

    frequency_: Counter

    def fit(self, days: Sequence[Sequence[str]]):
        """Train from scratch on per-day activity sequences."""
        self._reset()
        return self.partial_fit(days)

    def partial_fit(self, days: Sequence[Sequence[str]]):  # pragma: no cover - abstract
        raise NotImplementedError

    def predict_proba(self, history: Sequence[str]) -> dict[str, float]:  # pragma: no cover - abstract
        raise NotImplementedError

    def scan_proba(self, day: Sequence[str]) -> list[dict[str, float]]:
        """``[predict_proba(day[:t]) for t in range(len(day))]``."""
        return [self.predict_proba(day[:t]) for t in range(len(day))]

    def ranked(self, distribution: Mapping[str, float]) -> list[str]:
        return rank(distribution, self.frequency_)

    def predict(self, history: Sequence[str]) -> str | None:
        """Most probable next activity (ties: training frequency, then name)."""
        ranked = self.ranked(self.predict_proba(history))
        return ranked[0] if ranked else None

    def confidence(self, history: Sequence[str]) -> float:
        """The top probability: what the gate and the robot's action threshold look at."""
        return max(self.predict_proba(history).values(), default=0.0)
