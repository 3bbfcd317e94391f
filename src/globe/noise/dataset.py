"""HOMER-Noise on disk: generate it, write it as ordinary household folders plus a manifest of
every injected movement, and read it back as datasets to train and test on.

Layout: ``OUT/<type>/<level>/Household<X>/{nodes.csv,train/,test/}`` (read by the normal loader)
and ``OUT/<type>/<level>/manifest.csv``; ``OUT/summary.json`` counts what was injected.
"""

from __future__ import annotations

import csv
import json
import time
from collections import Counter
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable, Iterable, Sequence

from globe.config import NoiseConfig
from globe.data.csv_logs import load_household, write_day, write_nodes
from globe.data.records import Household
from globe.noise.generate import Injection, Proposals, apply, propose
from globe.noise.proposals import Scorer

MANIFEST_COLUMNS = ("household", "split", "day", "step", "minute", "object", "from", "to", "noise_type", "source")


def level_dir(root: Path, noise_type: str, level: float) -> Path:
    return Path(root) / noise_type / f"{level:g}"


def write_level(root: Path, households: Sequence[Household], proposals: dict[tuple[str, str], Proposals],
                noise_type: str, level: float, written_households: dict[tuple[Path, str], Household] | None = None
                ) -> list[Injection]:
    """Write one (type, level) dataset; returns the injections it contains. ``written_households``
    receives each noisy household as :func:`noisy_dataset` would read it back (its key)."""
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
        if written_households is not None:
            written_households[(folder, h.name)] = noisy
    write_manifest(folder / "manifest.csv", written)
    return written


def write_manifest(path: Path, injections: Iterable[Injection]) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow(MANIFEST_COLUMNS)
        for i in sorted(injections, key=lambda i: (i.household, i.day, i.step, i.obj)):
            split, day = i.day.split("/", 1)
            writer.writerow((i.household, split, day, i.step, i.minute, i.obj, i.source, i.target, i.noise_type,
                             i.origin))


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


def generate_dataset(noise: NoiseConfig, households: Sequence[Household], noise_dir: Path, scorer: Scorer,
                     progress: Callable[[str], None] | None = None,
                     written_households: dict[tuple[Path, str], Household] | None = None) -> dict:
    """Propose at level 1.0 once per (home, type), then write every level (nested subsets) and
    ``summary.json``; returns the summary. ``written_households`` receives the noisy households
    as :func:`noisy_dataset` reads them (pass it on as ``loaded``: nothing is parsed again)."""
    proposals: dict[tuple[str, str], Proposals] = {}
    started = time.perf_counter()
    for noise_type in noise.types:
        for h in households:
            if progress:
                progress(f"proposing {noise_type} disturbances in {h.name}")
            proposals[(h.name, noise_type)] = propose(h, noise_type, scorer, seed=noise.seed, rate=noise.rate,
                                                      temperature=noise.temperature)
    for noise_type in noise.types:
        for level in noise.levels:
            write_level(noise_dir, households, proposals, noise_type, level, written_households)
    out = summary(proposals, noise.levels)
    out |= {"seed": noise.seed, "rate": noise.rate, "temperature": noise.temperature, "scorer": scorer.name,
            "seconds": round(time.perf_counter() - started, 2)}
    write_summary(noise_dir, out)
    return out


def read_summary(root: Path) -> dict | None:
    """The summary of a dataset generated earlier, or None if there is none."""
    path = Path(root) / "summary.json"
    return json.loads(path.read_text(encoding="utf-8")) if path.is_file() else None


CLEAN = "clean"


@dataclass(frozen=True, slots=True)
class Dataset:
    """Households to train and test on, and the injected test movements."""

    name: str
    households: list[Household]
    injected: set[tuple[str, str, int, str]]


def clean_dataset(households: Sequence[Household]) -> Dataset:
    return Dataset(CLEAN, list(households), set())


def noisy_dataset(root: Path, noise_type: str, train_level: float, test_level: float, names: Sequence[str],
                  loaded: dict[tuple[Path, str], Household] | None = None) -> Dataset:
    """Train at ``train_level``, test at ``test_level``; ``loaded`` keeps households already read
    (the suite reads each level's folder for several datasets) or just written
    (:func:`generate_dataset`'s ``written_households``)."""
    loaded = {} if loaded is None else loaded

    def load(level: float, name: str) -> Household:
        folder = level_dir(root, noise_type, level)
        if (folder, name) not in loaded:
            loaded[(folder, name)] = load_household(folder, name)
        return loaded[(folder, name)]

    out = []
    for name in names:
        train, test = load(train_level, name), load(test_level, name)
        out.append(replace(train, test=test.test))
    return Dataset(noise_type, out, read_manifest(level_dir(root, noise_type, test_level) / "manifest.csv"))
