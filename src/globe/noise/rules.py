"""What each kind of disturber can physically do in a given home.

Locations are nodes of the home (``class#id``). Rooms stand for their floor. A pet cannot open
closed furniture or reach high surfaces; a toddler reaches what is low and cannot get at
high or closed places, nor at things kept out of a child's reach.
"""

from __future__ import annotations

from typing import Literal

from globe.data.records import Household

NoiseType = Literal["person", "pet", "toddler"]

CLOSED = frozenset({"fridge", "kitchen_cabinet", "cupboard", "bathroom_cabinet", "dresser", "filing_cabinet",
                    "microwave", "closet", "dishwasher", "washing_machine", "coffe_maker", "oven"})
HIGH = frozenset({"kitchen_counter", "sink", "stove", "bathroom_counter", "bookshelf", "kitchen_cabinet",
                  "bathroom_cabinet", "microwave", "coffe_maker", "toothbrush_holder", "knifeblock", "fridge"})
LOW_SURFACES = frozenset({"sofa", "chair", "table", "tvstand", "mat", "bed", "desk", "coffee_table"})
HEAVY = frozenset({"vacuum_cleaner", "instrument_guitar", "cd_player", "radio", "trashcan", "knifeblock",
                   "toothbrush_holder", "groceries"})
OUT_OF_CHILD_REACH = frozenset({"knife", "razor", "painkillers", "cleaning_solution", "wine", "oil", "trashbag"})
NOT_DESTINATIONS = frozenset({"home", "outside"})


class HomeRules:
    """Validity of a movement of ``obj`` from ``source`` to ``target`` for one noise type."""

    def __init__(self, household: Household) -> None:
        self.household = household
        self.parent = {n.node: n.start_location for n in household.nodes}
        self.category = {n.node: n.category for n in household.nodes}
        self.cls = {n.node: n.cls for n in household.nodes}
        self.movable_nodes = {n.cls: n.node for n in household.nodes if n.movable}
        self.static = [n.node for n in household.nodes if not n.movable]

    def room_of(self, node: str) -> str | None:
        """The room a static node stands in (objects: pass their location)."""
        seen = set()
        while node not in seen:
            seen.add(node)
            if self.category.get(node) == "Rooms":
                return node
            node = self.parent.get(node, node)
        return None

    def support(self, location: str, locations: dict[str, str]) -> str:
        """The static node under a location (an object on a plate on a table -> the table)."""
        seen = set()
        while self.cls.get(location) in self.movable_nodes and location not in seen:
            seen.add(location)
            location = locations.get(self.cls[location], location)
        return location

    def reachable_source(self, noise_type: NoiseType, obj: str, support: str) -> bool:
        cls = self.cls.get(support, "")
        if noise_type == "person":
            return True
        if noise_type == "pet":
            return obj not in HEAVY and cls not in CLOSED and cls not in HIGH
        return (obj not in HEAVY and obj not in OUT_OF_CHILD_REACH and cls not in HIGH
                and (cls not in CLOSED or cls in ("cupboard", "dresser")))

    def destinations(self, noise_type: NoiseType, support: str) -> list[str]:
        """Static nodes the disturber could put the object on (rooms mean their floor)."""
        here_room = self.room_of(support)
        out = []
        for node in self.static:
            cls, cat = self.cls[node], self.category[node]
            if cls in NOT_DESTINATIONS or (cat in ("Home", "Decor") and cls != "mat"):
                continue
            if noise_type == "pet":
                ok = (cat == "Rooms" and node == here_room) or (cls in LOW_SURFACES and self.room_of(node) == here_room)
            elif noise_type == "toddler":
                ok = cat == "Rooms" or cls in LOW_SURFACES
            else:
                ok = cat in ("Rooms", "Furniture", "Appliances") or cls == "mat"
            if ok and node != support:
                out.append(node)
        return out

    def valid(self, noise_type: NoiseType, obj: str, source: str, target: str, locations: dict[str, str]) -> str | None:
        """None if the movement is possible; otherwise why not."""
        if obj not in self.movable_nodes:
            return "unknown object"
        if target not in self.cls:
            return "unknown destination"
        if target == source:
            return "already there"
        support = self.support(source, locations)
        if not self.reachable_source(noise_type, obj, support):
            return "source out of reach"
        if target not in self.destinations(noise_type, support):
            return "destination not allowed"
        return None
