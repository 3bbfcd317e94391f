"""What both counting models share: scikit-learn-style parameters, fitted checks, ranking."""

from __future__ import annotations

from typing import Any, ClassVar, Hashable, Mapping

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


def rank(distribution: Mapping[Hashable, float], frequency: Mapping[Hashable, int]) -> list[Hashable]:
    """Labels by probability; ties by training frequency, then by label (deterministic)."""
    return sorted(distribution, key=lambda w: (-distribution[w], -frequency.get(w, 0), str(w)))
