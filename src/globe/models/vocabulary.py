"""One label <-> integer mapping, built at fit and shared by everything that counts or infers.

Labels are numbered once, in the order given (a model passes its sorted classes), and the
mapping is frozen: a label the models never saw gets a number only in an *extended* copy, whose
first numbers are those of the original, so arrays indexed by the old numbers stay valid.
"""

from __future__ import annotations

from typing import Iterable, Iterator, Sequence

import numpy as np


class Vocabulary(Sequence[str]):
    """An immutable sequence of distinct labels; ``index(label)`` is a label's number."""

    __slots__ = ("_labels", "_codes")

    def __init__(self, labels: Iterable[str] = ()) -> None:
        self._labels: tuple[str, ...] = tuple(dict.fromkeys(labels))
        self._codes: dict[str, int] = {label: i for i, label in enumerate(self._labels)}

    def __len__(self) -> int:
        return len(self._labels)

    def __getitem__(self, i):
        return self._labels[i]

    def __iter__(self) -> Iterator[str]:
        return iter(self._labels)

    def __contains__(self, label: object) -> bool:
        return label in self._codes

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Vocabulary) and other._labels == self._labels

    def __hash__(self) -> int:
        return hash(self._labels)

    def __repr__(self) -> str:
        return f"Vocabulary({list(self._labels)!r})"

    @property
    def labels(self) -> tuple[str, ...]:
        return self._labels

    def index(self, label: str, start: int = 0, stop: int | None = None) -> int:
        """The number of ``label`` (a KeyError names a label this vocabulary does not hold)."""
        return self._codes[label]

    def get(self, label: str, default: int = -1) -> int:
        return self._codes.get(label, default)

    def indices(self, labels: Iterable[str], default: int = -1) -> list[int]:
        """The numbers of ``labels`` as a list (``default`` for labels not held)."""
        get = self._codes.get
        return [get(label, default) for label in labels]

    def encode(self, labels: Iterable[str], default: int = -1) -> np.ndarray:
        """The numbers of ``labels`` (``default`` for labels not held)."""
        codes = self._codes
        return np.fromiter((codes.get(label, default) for label in labels), dtype=np.int64)

    def extended(self, labels: Iterable[str]) -> "Vocabulary":
        """This vocabulary with the labels it does not hold appended (itself when there are none)."""
        new = [label for label in dict.fromkeys(labels) if label not in self._codes]
        return Vocabulary(self._labels + tuple(new)) if new else self
