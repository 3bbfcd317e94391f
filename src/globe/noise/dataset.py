"""Write HOMER-Noise as ordinary household folders plus a manifest of every injected movement.

Layout: ``OUT/<type>/<level>/Household<X>/{nodes.csv,train/,test/}`` (read by the normal loader)
and ``OUT/<type>/<level>/manifest.csv``; ``OUT/summary.json`` counts what was injected.
"""

from __future__ import annotations

import csv
import json
from collections import Counter
from pathlib import Path
from typing import Iterable, Sequence

from globe.data.csv_logs import write_day, write_nodes
from globe.data.records import Household
from globe.noise.generate import Injection, Proposals, apply

MANIFEST_COLUMNS = ("household", "split", "day", "step", "minute", "object", "from", "to", "noise_type", "source")


def level_dir(root: Path, noise_type: str, level: float) -> Path:
    return Path(root) / noise_type / f"{level:g}"


def write_level(root: Path, households: Sequence[Household], proposals: dict[tuple[str, str], Proposals],
                noise_type: str, level: float) -> list[Injection]:
    """Write one (type, level) dataset; returns the injections it contains."""
    folder = level_dir(root, noise_type, level)
    written: list[Injection] = []
    for h in households:
        chosen = proposals[(h.name, noise_type)].at_level(level)
        noisy = apply(h, chosen)
        out = folder / f"Household{h.name}"
        write_nodes(out / "nodes.csv", h.nodes)
        for day in noisy.train + noisy.test:
            write_day(out / f"{day.name}.csv", day, h.objects)
        written.extend(chosen)
    write_manifest(folder / "manifest.csv", written)
    return written


def write_manifest(path: Path, injections: Iterable[Injection]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow(MANIFEST_COLUMNS)
        for i in sorted(injections, key=lambda i: (i.household, i.day, i.step, i.obj)):
            split, day = i.day.split("/", 1)
            writer.writerow((i.household, split, day, i.step, i.minute, i.obj, i.source, i.target, i.noise_type, i.origin))


def read_manifest(path: Path) -> set[tuple[str, str, int, str]]:
    """(household, "split/day", step, object) of every injected movement."""
    with Path(path).open(newline="", encoding="utf-8") as fh:
        return {(r["household"], f"{r['split']}/{r['day']}", int(r["step"]), r["object"]) for r in csv.DictReader(fh)}


def summary(proposals: dict[tuple[str, str], Proposals], levels: Sequence[float]) -> dict:
    out: dict = {"levels": list(levels), "types": {}}
    for (_house, noise_type), props in sorted(proposals.items()):
        entry = out["types"].setdefault(noise_type, {"proposed_valid": 0, "dropped": Counter(), "per_level": {},
                                                     "objects": Counter(), "destinations": Counter()})
        entry["proposed_valid"] += len(props.injections)
        entry["dropped"].update(props.dropped)
        for level in levels:
            entry["per_level"][f"{level:g}"] = entry["per_level"].get(f"{level:g}", 0) + len(props.at_level(level))
        entry["objects"].update(i.obj for i in props.injections)
        entry["destinations"].update(i.target.split("#")[0] for i in props.injections)
    for entry in out["types"].values():
        entry["dropped"] = dict(entry["dropped"].most_common())
        entry["objects"] = dict(entry["objects"].most_common(10))
        entry["destinations"] = dict(entry["destinations"].most_common(10))
    return out


def write_summary(root: Path, data: dict) -> None:
    Path(root).mkdir(parents=True, exist_ok=True)
    (Path(root) / "summary.json").write_text(json.dumps(data, indent=2) + "\n", encoding="utf-8")
