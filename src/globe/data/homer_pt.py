"""Importer of native HOMER+ files (``processed_seqLM_coarse/{train,test}/NNN.pt``) into CSV logs.

Optional: needs ``globe[torch]``. Each ``.pt`` is a pickled dict with ``edges`` [T, N, N]
(one-hot child -> parent per step), ``times`` [T], ``activity`` [T] (indices into
``common_data.json``'s ``activities``), ``active_edges`` [N, N] (non-zero rows = movable nodes),
``node_ids`` and ``class_names``. Node categories come from ``common_data.json``.
"""

from __future__ import annotations

import json
from pathlib import Path

from globe.data.csv_logs import write_day, write_nodes
from globe.data.records import Day, Node
from globe.errors import DataError, MissingExtraError

SUBDIR = "processed_seqLM_coarse"


def _torch():
    try:
        import torch
    except ImportError as err:
        raise MissingExtraError("torch", "torch") from err
    return torch


def _find_root(source: Path) -> Path:
    source = Path(source)
    for cand in (source, source / SUBDIR):
        if (cand / "common_data.json").is_file() and ((cand / "train").is_dir() or (cand / "test").is_dir()):
            return cand
    raise DataError(f"no {SUBDIR} folder with common_data.json and train/ or test/ here", source=str(source))


def _load_pt(path: Path) -> dict:
    torch = _torch()
    try:
        return torch.load(path, weights_only=False, map_location="cpu")
    except Exception as err:  # torch raises many types for corrupt pickles
        raise DataError(f"cannot read native HOMER+ file: {err}", source=str(path)) from err


def _labels(raw: dict) -> list[str]:
    return [f"{c}#{int(i)}" for c, i in zip(raw["class_names"], raw["node_ids"])]


def convert_day(raw: dict, activities: list[str], name: str, source: str = "") -> tuple[Day, list[str], list[int]]:
    """One native day -> (Day, node labels, indices of the movable nodes)."""
    labels = _labels(raw)
    movable = [i for i in range(len(labels)) if bool(raw["active_edges"][i].any())]
    parents = raw["edges"].argmax(-1).tolist()  # [T][N]
    times = [int(t) for t in raw["times"].tolist()]
    acts = [activities[int(a)] for a in raw["activity"].tolist()]
    locations = tuple(tuple(labels[step[i]] for i in movable) for step in parents)
    return Day(name, tuple(times), tuple(acts), locations, source), labels, movable


def import_household(source: Path, dest: Path) -> list[Path]:
    """Convert every ``.pt`` under ``source`` into ``dest/{train,test}/NNN.csv`` plus ``nodes.csv``."""
    root = _find_root(source)
    common_path = root / "common_data.json"
    try:
        common = json.loads(common_path.read_text(encoding="utf-8"))
        activities = [str(a) for a in common["activities"]]
        node_labels = (f"{c}#{i}" for c, i in zip(common["node_classes"], common["node_ids"]))
        categories = dict(zip(node_labels, common["node_categories"]))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
        raise DataError(f"cannot read: {err}", source=str(common_path)) from err
    except (KeyError, TypeError) as err:
        raise DataError(f"not HOMER+'s common_data.json (missing or malformed {err})", source=str(common_path)) from err
    written: list[Path] = []
    nodes_written = False
    for split in ("train", "test"):
        for pt in sorted((root / split).glob("*.pt")):
            raw = _load_pt(pt)
            try:
                day, labels, movable = convert_day(raw, activities, f"{split}/{pt.stem}", str(pt))
            except (KeyError, IndexError, TypeError, ValueError, AttributeError) as err:
                raise DataError(f"not a native HOMER+ day ({type(err).__name__}: {err})", source=str(pt)) from err
            objects = tuple(labels[i].split("#")[0] for i in movable)
            target = Path(dest) / split / f"{pt.stem}.csv"
            write_day(target, day, objects)
            written.append(target)
            if not nodes_written:
                first = raw["edges"][0].argmax(-1).tolist()
                mov = set(movable)
                nodes = [Node(lab, lab.split("#")[0], categories.get(lab, ""), i in mov, labels[first[i]])
                         for i, lab in enumerate(labels)]
                write_nodes(Path(dest) / "nodes.csv", nodes)
                nodes_written = True
    if not written:
        raise DataError("no .pt day files under train/ or test/", source=str(root))
    return written
