"""A tiny, valid household written from code: the base every corpus case and fuzz test mutates."""

from __future__ import annotations

from pathlib import Path

NODES = [
    ("home#1", "home", "Home", 0, "home#1"),
    ("kitchen#2", "kitchen", "Rooms", 0, "home#1"),
    ("counter#3", "counter", "Furniture", 0, "kitchen#2"),
    ("table#4", "table", "Furniture", 0, "kitchen#2"),
    ("cup#5", "cup", "placable_objects", 1, "counter#3"),
    ("plate#6", "plate", "placable_objects", 1, "counter#3"),
]
OBJECTS = ("cup", "plate")
ACTIVITIES = ("sleeping", "breakfast", "breakfast", "cleaning", "idle", "idle", "reading", "reading", "idle",
              "sleeping", "sleeping")


def nodes_text(nodes=NODES) -> str:
    return "node,class,category,movable,start_location\n" + "".join(",".join(map(str, n)) + "\n" for n in nodes)


def day_rows(shift: int = 0) -> list[list[str]]:
    """11 rows, minutes 360..460 every 10; the cup and the plate move to the table at breakfast."""
    rows = []
    for t, activity in enumerate(ACTIVITIES):
        cup = "table#4" if 2 <= t + shift % 2 <= 4 else "counter#3"
        plate = "table#4" if 2 <= t <= 3 else "counter#3"
        rows.append([str(360 + 10 * t), activity, cup, plate])
    return rows


def day_text(rows: list[list[str]] | None = None, header: tuple[str, ...] = ("minute", "activity", *OBJECTS)) -> str:
    rows = day_rows() if rows is None else rows
    return ",".join(header) + "\n" + "".join(",".join(r) + "\n" for r in rows)


def write_home(root: Path, name: str = "HouseholdT", *, train: int = 3, test: int = 1,
               nodes: str | None = None) -> Path:
    """``root/name`` with ``nodes.csv``, ``train/000..`` and ``test/000..``; returns the folder."""
    home = Path(root) / name
    (home / "train").mkdir(parents=True)
    (home / "nodes.csv").write_text(nodes_text() if nodes is None else nodes, encoding="utf-8")
    for i in range(train):
        (home / "train" / f"{i:03d}.csv").write_text(day_text(day_rows(i)), encoding="utf-8")
    if test:
        (home / "test").mkdir()
        for i in range(test):
            (home / "test" / f"{i:03d}.csv").write_text(day_text(day_rows(i + 1)), encoding="utf-8")
    return home


def activity_only(root: Path, name: str = "HouseholdQ", *, train: int = 3, test: int = 1) -> Path:
    """A home with no tracked objects: every node fixed, day files with minute and activity only."""
    nodes = nodes_text([n[:3] + (0,) + n[4:] for n in NODES])
    home = write_home(root, name, train=0, test=0, nodes=nodes)
    for split, count in (("train", train), ("test", test)):
        (home / split).mkdir(exist_ok=True)
        for i in range(count):
            rows = [r[:2] for r in day_rows(i)]
            (home / split / f"{i:03d}.csv").write_text(day_text(rows, ("minute", "activity")), encoding="utf-8")
    return home
