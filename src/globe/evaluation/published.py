"""Figures published in the GLOBE paper (HOMER+), shown beside ours, always labelled as such."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

from globe.data.records import Household, is_use_place
from globe.evaluation.selection import fingerprint

# method -> (activity F1, object F1, mean F1), weighted F1 averaged over households A, B, C
TABLE1 = {
    "globe": (0.80, 0.65, 0.73),
    "ngram": (0.79, 0.64, 0.72),
    "slate_pro": (0.78, 0.69, 0.74),
    "llm_only": (0.57, 0.00, 0.29),
}
# method -> (training s, inference s) for the whole test split
TABLE2 = {"globe": (8.33, 192.0), "ngram": (8.33, 0.86)}
# method -> published mean F1 only (the GLOBE paper quotes STOT's mean from SLaTe-PRO's paper)
TABLE1_MEAN_ONLY = {"stot": 0.43}

# HOMER+'s households by the content of their days (selection.fingerprint of train, test): the
# published figures are about these days and are shown beside results on them only.
HOMER_PLUS_DAYS = {
    ("ad40706edad37ded650c0dc44b8f3a00", "341c04d3fe8735e4c5e2205cac5ec218"),  # A
    ("1e360edaa1c15fa11d126be1ad6ae385", "6cdea943d41abd87a50acf44aa970db5"),  # B
    ("ea3c8cfc854509212baf4be732e7eee4", "5b8a198b14d9f7c3a7f125c88436b4c1"),  # C
}


RELOCATIONS = "every relocation"
DEPARTURES = "departures only (a return from a use place is no use)"


@dataclass(frozen=True, slots=True)
class DataScope:
    """What a results folder is about: the title its tables and plots carry, and whether the
    paper's published figures (all measured on HOMER+) may stand beside it."""

    title: str
    households: tuple[str, ...]
    homer_plus: bool
    uses: str = RELOCATIONS  # which object movements are scored as uses (:func:`uses_rule`)

    @classmethod
    def of(cls, households: Sequence[Household]) -> "DataScope":
        """HOMER+ when every household's days are HOMER+'s (by content, wherever the files are),
        else the households by name."""
        names = tuple(h.name for h in households)
        homer = bool(households) and all(
            (fingerprint(h.train), fingerprint(h.test)) in HOMER_PLUS_DAYS for h in households)
        uses = uses_rule(households)
        if homer:
            return cls("HOMER+", names, True, uses)
        return cls(("household " if len(names) == 1 else "households ") + ", ".join(names), names, False, uses)

    def as_dict(self) -> dict:
        return {"title": self.title, "households": list(self.households), "homer_plus": self.homer_plus,
                "uses": self.uses}

    @classmethod
    def from_dict(cls, payload: dict) -> "DataScope":
        return cls(str(payload["title"]), tuple(payload["households"]), bool(payload["homer_plus"]),
                   str(payload.get("uses", RELOCATIONS)))


def uses_rule(households: Sequence[Household]) -> str:
    """Which rule the object scores of ``households`` follow (:mod:`globe.sequences.movements`):
    every relocation (HOMER+'s protocol) where the map has no use place, departures only where it
    has; per household when they differ."""
    def rule(h: Household) -> str:
        return DEPARTURES if any(is_use_place(n.node) for n in h.nodes) else RELOCATIONS

    found = {h.name: rule(h) for h in households}
    if len(set(found.values())) <= 1:
        return next(iter(found.values()), RELOCATIONS)
    return "; ".join(f"{name}: {r}" for name, r in found.items())
