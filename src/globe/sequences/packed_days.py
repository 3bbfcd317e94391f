"""Training days kept as numbers, for a model that must count them again when it learns a day.

A day as parsed holds a tuple of location labels per distinct row and an int object per minute:
about 18 KB for a HOMER+ day, over a megabyte for a household's 65. Packed, each step is three
4-byte numbers (minute, activity, row) and each distinct row of locations is stored once for all
days, about 3 KB a day. Reading gives back :class:`Day` records equal to the ones packed.
"""

from __future__ import annotations

from array import array
from itertools import accumulate, chain
from typing import Iterable, Iterator, Sequence, overload

import numpy as np

from globe.data.records import Day


class PackedDays(Sequence[Day]):
    """An immutable sequence of days, stored compactly (see module doc)."""

    __slots__ = ("_labels", "_meta", "_offsets", "_minutes", "_activities", "_rows", "_row_start", "_row_labels")

    def __init__(self, days: Iterable[Day] = ()) -> None:
        days = tuple(days)
        rows: dict[tuple[str, ...], int] = {}  # distinct rows of locations, first seen first
        steps = array("i")  # step -> its row
        seen: dict[int, int] = {}  # id of a row object -> its number: parsed days share equal rows' tuples
        for d in days:
            for row in d.locations:
                number = seen.get(id(row))
                if number is None:  # rows are numbered by value; the days are alive, so the ids are stable
                    number = seen[id(row)] = rows.setdefault(row, len(rows))
                steps.append(number)
        labels = dict.fromkeys(chain(chain.from_iterable(d.activities for d in days), chain.from_iterable(rows)))
        ids = {label: i for i, label in enumerate(labels)}
        self._labels: list[str] = list(labels)  # number -> label (activities and locations)
        self._meta: list[tuple[str, str]] = [(d.name, d.source) for d in days]  # (name, source) of each day
        self._offsets = array("q", accumulate(map(len, days), initial=0))  # day i: steps offsets[i] .. offsets[i + 1]
        self._minutes = array("i", chain.from_iterable(d.minutes for d in days))
        self._activities = array("i", map(ids.__getitem__, chain.from_iterable(d.activities for d in days)))
        self._rows = steps
        # distinct row r: labels _row_labels[_row_start[r] .. _row_start[r + 1]]
        self._row_start = array("i", accumulate(map(len, rows), initial=0))
        self._row_labels = array("i", map(ids.__getitem__, chain.from_iterable(rows)))

    def __len__(self) -> int:
        return len(self._meta)

    def extended(self, days: Iterable[Day]) -> "PackedDays":
        """These days and then ``days``, packed: the days packed already are not read back (an
        online model learning a day a time would otherwise unpack and pack all its days again)."""
        labels = list(self._labels)
        ids = {label: i for i, label in enumerate(labels)}
        rows = {tuple(labels[x] for x in self._row_labels[a:b]): r
                for r, (a, b) in enumerate(zip(self._row_start, self._row_start[1:]))}
        out = PackedDays()
        out._meta, out._minutes = list(self._meta), array("i", self._minutes)
        out._activities = array("i", self._activities)
        out._offsets, out._rows = array("q", self._offsets), array("i", self._rows)
        out._row_start, out._row_labels = array("i", self._row_start), array("i", self._row_labels)
        for d in days:
            for label in chain(d.activities, chain.from_iterable(d.locations)):
                if label not in ids:
                    ids[label] = len(labels)
                    labels.append(label)
            for row in d.locations:
                number = rows.get(row)
                if number is None:
                    number = rows[row] = len(rows)
                    out._row_labels.extend(map(ids.__getitem__, row))
                    out._row_start.append(len(out._row_labels))
                out._rows.append(number)
            out._meta.append((d.name, d.source))
            out._offsets.append(out._offsets[-1] + len(d))
            out._minutes.extend(d.minutes)
            out._activities.extend(map(ids.__getitem__, d.activities))
        out._labels = labels
        return out

    def coded_rows(self, width: int) -> tuple[np.ndarray, np.ndarray, list[str]]:
        """The locations as numbers, for counting without hashing rows again: each step's
        distinct-row number (all days in order; day i is steps ``offsets[i] .. offsets[i + 1]``),
        the distinct rows as label numbers (rows x ``width``), and number -> label."""
        starts = np.frombuffer(self._row_start, dtype=np.int32)
        if np.any(np.diff(starts) != width):
            raise ValueError(f"every row of locations must have {width} cells")
        steps = np.frombuffer(self._rows, dtype=np.int32).astype(int)
        table = np.frombuffer(self._row_labels, dtype=np.int32).astype(int).reshape(len(starts) - 1, width)
        return steps, table, self._labels

    def coded_activities(self) -> np.ndarray:
        """Each step's activity as a label number of :meth:`coded_rows` (all days in order)."""
        return np.frombuffer(self._activities, dtype=np.int32).astype(int)

    @property
    def offsets(self) -> tuple[int, ...]:
        """Day i is steps ``offsets[i] .. offsets[i + 1]`` of :meth:`coded_rows`."""
        return tuple(self._offsets)

    @overload
    def __getitem__(self, i: int) -> Day: ...

    @overload
    def __getitem__(self, i: slice) -> Sequence[Day]: ...

    def __getitem__(self, i: int | slice) -> Day | Sequence[Day]:
        if isinstance(i, slice):
            return tuple(self[k] for k in range(*i.indices(len(self))))
        if not -len(self) <= i < len(self):
            raise IndexError("day index out of range")
        return self._day(i % len(self), {})

    def __iter__(self) -> Iterator[Day]:
        decoded: dict[int, tuple[str, ...]] = {}  # rows shared by the days read, as when parsed
        for i in range(len(self)):
            yield self._day(i, decoded)

    def _day(self, i: int, decoded: dict[int, tuple[str, ...]]) -> Day:
        lo, hi = self._offsets[i], self._offsets[i + 1]
        labels = self._labels
        locations = []
        for r in self._rows[lo:hi]:
            row = decoded.get(r)
            if row is None:
                cells = self._row_labels[self._row_start[r]: self._row_start[r + 1]]
                row = decoded[r] = tuple(labels[x] for x in cells)
            locations.append(row)
        name, source = self._meta[i]
        return Day(name, tuple(self._minutes[lo:hi]), tuple(labels[a] for a in self._activities[lo:hi]),
                   tuple(locations), source)


__all__ = ["PackedDays"]
