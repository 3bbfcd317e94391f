"""Frozen records for a household's observation logs (the data every later layer reads)."""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from datetime import date
from typing import Literal

Split = Literal["train", "test"]
IN_USE_CLASS = "in_use"
"""The class of a place where an object is while a person uses it (the importers put a sensor's
object there while the sensor is on): no robot fetches an object from it."""


def is_use_place(label: str) -> bool:
    """Whether the place ``label`` ("class#id") is of class ``in_use``. An object moving *into* such
    a place is taken by the person (a use); moving *out of* it is put back, which is no use: it is
    foreseen by anyone who sees the object in use, so it is neither learnt nor scored as one."""
    return label.startswith(_USE_PREFIX) or label == IN_USE_CLASS
_USE_PREFIX = IN_USE_CLASS + "#"
_ISO_DATE = re.compile(r"[0-9]{4}-[0-9]{2}-[0-9]{2}")


@dataclass(frozen=True, slots=True)
class Node:
    """One node of the home: a room, furniture, an appliance or a movable object."""

    node: str  # "class#id", the node's unique label
    cls: str
    category: str
    movable: bool
    start_location: str


def named_date(name: str) -> date | None:
    """The date a day's name or file name gives (``train/2024-04-13``, ``2024-04-13.csv``, as the
    importers and the service name days), else None."""
    stem = name.rsplit("/", 1)[-1].removesuffix(".csv")
    if not _ISO_DATE.fullmatch(stem):
        return None
    try:
        return date.fromisoformat(stem)
    except ValueError:
        return None


@dataclass(frozen=True, slots=True)
class Day:
    """One observed day: the activity and every movable object's location at each step."""

    name: str  # e.g. "train/012"
    minutes: tuple[int, ...]
    activities: tuple[str, ...]
    locations: tuple[tuple[str, ...], ...]  # [step][object column]
    source: str = ""
    covering: tuple[str, ...] | None = None  # per step: the activity covering most of it (imported logs), if known
    observed: tuple[str, ...] | None = None  # per step: the activity as GLOBE saw it (recognised), if not annotated

    def __len__(self) -> int:
        return len(self.minutes)

    @property
    def seen(self) -> tuple[str, ...]:
        """The activities a model is shown (:attr:`observed` where set, else the annotation): the
        evaluation conditions on these and scores against :attr:`activities`, so a day whose
        activities were recognised from sensors is scored as a live service would be."""
        return self.activities if self.observed is None else self.observed

    @property
    def calendar_date(self) -> date | None:
        """The day's date when it is named by it (:func:`named_date`), else None: a day without a
        date is simply one of no known weekday."""
        return named_date(self.name)

    @property
    def weekday(self) -> int | None:
        """Monday 0 .. Sunday 6 (:attr:`calendar_date`), or None: what models that know the day of
        the week read."""
        when = self.calendar_date
        return None if when is None else when.weekday()


@dataclass(frozen=True, slots=True)
class Household:
    """A home: its nodes, its movable object columns and its train/test days."""

    name: str
    nodes: tuple[Node, ...]
    objects: tuple[str, ...]  # day-file object columns, in file order
    train: tuple[Day, ...]
    test: tuple[Day, ...]
    source: str = ""
    _node_index: dict[str, Node] = field(default_factory=dict, compare=False, repr=False)

    def __post_init__(self) -> None:
        self._node_index.update({n.node: n for n in self.nodes})

    def node(self, label: str) -> Node | None:
        return self._node_index.get(label)

    def place_name(self, label: str) -> str:
        """A place as a person names it: its class in words and the room it is in
        (``kitchen_counter#119`` -> "kitchen counter, dining room"; an ``in_use`` place -> "in use,
        kitchen"); a label not on the map, as it is."""
        node = self.node(label)
        if node is None:
            return label
        name = node.cls.replace("_", " ")
        if node.category.lower() == "rooms":
            return name
        around = self.node(node.start_location)
        for _ in range(len(self.nodes)):  # up the map to the room (a map may loop: bounded)
            if around is None or around.category.lower() == "rooms":
                break
            around = self.node(around.start_location)
        if around is None or around.category.lower() != "rooms":
            return name
        return f"{name}, {around.cls.replace('_', ' ')}"

    @property
    def locations(self) -> frozenset[str]:
        """Every label an object may be at."""
        return frozenset(self._node_index)

    @property
    def use_places(self) -> frozenset[str]:
        """The places of class ``in_use``: an object there is held by the person, and none is
        fetched from one or just put back to one (:func:`~globe.inference.fetch_policy.left_alone`)."""
        return frozenset(n.node for n in self.nodes if n.cls == IN_USE_CLASS)

    def days(self, split: Split) -> tuple[Day, ...]:
        return self.train if split == "train" else self.test


def map_fingerprint(nodes: tuple[Node, ...] | list[Node], objects: tuple[str, ...]) -> str:
    """A stable hash of a home's map (every node and the object columns, in order): a saved model
    records it so that it is never loaded for another home's map."""
    import hashlib
    import json

    rows = [[n.node, n.cls, n.category, n.movable, n.start_location] for n in nodes]
    payload = json.dumps([rows, list(objects)], ensure_ascii=True, separators=(",", ":"))
    return "sha256:" + hashlib.sha256(payload.encode("ascii")).hexdigest()
