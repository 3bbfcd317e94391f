"""A simulated sensor home (no third-party data): the clock routine of :mod:`tests.simulated`
lived in rooms with the sensors a real home has, imperfect as theirs are.

Rooms: bedroom, bathroom, kitchen, living room, study and hall, each with a motion sensor (an
activation of 20-90 s, a few a minute while someone moves there, rarer while they sit); a front
door and a bathroom door (contacts firing on the way in and out), a bed and a sofa pressure mat
(on while lain or sat on), a toilet flush, a dining-chair mat, and the object sensors of the
clock home (kettle, fridge, cupboard, microwave) firing at the object's use. Imperfections: each
firing is missed with probability ``miss``; motion fires falsely in a random room about
``false_per_hour`` times an hour; on one day in ten the bathroom door is left open (its contact on
for hours); toileting and grooming share a room and differ only by the flush, as in real homes.
"""

from __future__ import annotations

import random
from datetime import date, timedelta
from pathlib import Path
from typing import Sequence

from globe.data.csv_logs import write_day, write_nodes
from globe.data.records import Day, Household
from globe.data.sensors import Sensor, SensorData, SensorDay, write_sensor_data
from tests.simulated import END, START, _Block, _clock_blocks, _day, _household, _random_blocks, _unsettled

SENSORS = (
    Sensor("M_bedroom", "motion", "bedroom"), Sensor("M_bathroom", "motion", "bathroom"),
    Sensor("M_kitchen", "motion", "kitchen"), Sensor("M_living", "motion", "living"),
    Sensor("M_study", "motion", "study"), Sensor("M_hall", "motion", "hall"),
    Sensor("D_front", "door", "hall"), Sensor("D_bathroom", "door", "bathroom"),
    Sensor("P_bed", "pressure", "bedroom"), Sensor("P_sofa", "pressure", "living"),
    Sensor("P_chair", "pressure", "kitchen"), Sensor("F_toilet", "flush", "bathroom"),
    Sensor("C_kettle", "appliance", "kitchen", "kettle"), Sensor("C_fridge", "contact", "kitchen", "fridge"),
    Sensor("C_cupboard", "contact", "kitchen", "cupboard"), Sensor("C_microwave", "appliance", "kitchen", "microwave"),
)
_INDEX = {s.name: i for i, s in enumerate(SENSORS)}

# activity -> (room, motion firings an hour there, mat on throughout, extra firings at its start)
_PLACES: dict[str, tuple[str, float, str | None, tuple[str, ...]]] = {
    "sleeping": ("bedroom", 1.0, "P_bed", ()),
    "toileting": ("bathroom", 90.0, None, ("D_bathroom",)),
    "grooming": ("bathroom", 120.0, None, ("D_bathroom",)),
    "breakfast": ("kitchen", 20.0, "P_chair", ()),
    "lunch": ("kitchen", 20.0, "P_chair", ()),
    "dinner": ("kitchen", 20.0, "P_chair", ()),
    "meal_preparation": ("kitchen", 150.0, None, ()),
    "washing_dishes": ("kitchen", 120.0, None, ()),
    "relax": ("living", 6.0, "P_sofa", ()),
    "work": ("study", 15.0, None, ()),
    "idle": ("", 40.0, None, ()),  # wandering: motion in the hall, the living room and the kitchen
    "leave_home": ("", 0.0, None, ("D_front",)),
}
_WANDER = ("hall", "living", "kitchen", "hall", "bedroom")


def sensor_home(days: int = 28, test: int = 7, step: int = 1, seed: int = 0, miss: float = 0.1,
                false_per_hour: float = 0.5, drift: float = 0.5, routine: bool = True) -> tuple[Household, SensorData]:
    """A household (days named by date from Monday 2024-01-01, activities annotated) and the
    activations of its sensors (see the module doc); without ``routine``, each day a random
    sequence of the same activities at random times (:func:`tests.simulated.random_home`'s rule)."""
    rng = random.Random(seed)
    out_days, events = [], {}
    for i in range(days):
        name = (date(2024, 1, 1) + timedelta(days=i)).isoformat()
        blocks = _unsettled(rng, _clock_blocks(rng, i % 7), drift) if routine else \
            _random_blocks(rng, tuple(_PLACES))
        out_days.append(_day(name, blocks, step))
        events[name] = _activations(rng, name, blocks, step, miss, false_per_hour, stuck=rng.random() < 0.1)
    return _household("Sensors", out_days, test), SensorData(SENSORS, events)


def write_home(folder: Path, home: Household, sensors: SensorData, train: Sequence[Day] | None = None) -> Path:
    """``home`` written as a household folder (``nodes.csv``, ``train/`` and ``test/`` day files,
    ``sensors.csv`` and ``events/``), as an import with its sensors writes it; ``train`` (default:
    the home's training days) the days written as labelled training days."""
    write_nodes(folder / "nodes.csv", home.nodes)
    for split, days in (("train", home.train if train is None else train), ("test", home.test)):
        for day in days:
            write_day(folder / split / f"{day.name}.csv", day, home.objects)
    write_sensor_data(folder, sensors)
    return folder


def _activations(rng: random.Random, name: str, blocks: list[_Block], step: int, miss: float, false_per_hour: float,
                 stuck: bool) -> SensorDay:
    """The day's activations, inside the span its rows cover (06:00 to the end of the 24:00 row's step)."""
    rows: list[tuple[int, float, float]] = []
    span = (START * 60.0, (END + step) * 60.0)

    def fire(sensor: str, start: float, end: float | None = None, sure: bool = False) -> None:
        if not sure and rng.random() < miss:
            return
        s = min(max(start, span[0]), span[1])
        e = min(max(end if end is not None else s, s), span[1])
        rows.append((_INDEX[sensor], round(s, 1), round(e, 1)))

    ends = [b.start for b in blocks[1:]] + [float(END + step)]
    for block, end in zip(blocks, ends):
        start_s, end_s = block.start * 60.0, end * 60.0
        if end_s <= start_s:
            continue
        room, rate, mat, at_start = _PLACES.get(block.activity, ("", 20.0, None, ()))
        for sensor in at_start:
            fire(sensor, start_s + rng.uniform(0, 30))
        if block.activity == "leave_home":
            fire("D_front", end_s - rng.uniform(0, 30))
        if block.activity == "toileting" and rng.random() < 0.9:
            fire("F_toilet", max(start_s, end_s - rng.uniform(30, 90)))
        if mat is not None:
            fire(mat, start_s + rng.uniform(10, 60), end_s - rng.uniform(0, 30), sure=True)
        t = start_s
        while rate > 0:
            t += rng.expovariate(rate / 3600)
            if t >= end_s:
                break
            where = room or rng.choice(_WANDER)
            fire(f"M_{where}", t, t + rng.uniform(20, 90))
        for obj, after in block.uses:  # the objects of the clock home, at their use
            fire(f"C_{obj}", start_s + after * 60.0, start_s + after * 60.0 + rng.uniform(5, 40), sure=True)
    t = span[0]
    while false_per_hour > 0:
        t += rng.expovariate(false_per_hour / 3600)
        if t >= span[1]:
            break
        fire(f"M_{rng.choice(('bedroom', 'bathroom', 'kitchen', 'living', 'study', 'hall'))}", t, t + 30, sure=True)
    if stuck:  # the bathroom door left open for hours
        at = rng.uniform(10 * 3600, 14 * 3600)
        fire("D_bathroom", at, at + rng.uniform(3, 6) * 3600, sure=True)
    return SensorDay.of(name, rows)
