"""Simulated homes that behave like real ones, written from code (no third-party data).

``clock_home``: one adult whose day follows the clock with jitter: asleep until about 07:00,
washing, breakfast, out at work on weekdays, meals around 12:30 and 19:00, television in the
evening, bed near 23:00; long stretches of ``idle`` and ``relax`` as annotated homes have, and
short uses of objects (a kettle, the fridge, a cupboard) at meals, shorter than a 10-minute step.
``random_home``: the same labels with runs of random length in random order, unrelated to the
clock, so nothing beats "the activity stays the same" by much.
"""

from __future__ import annotations

import random
from dataclasses import dataclass
from datetime import date, timedelta

from globe.data.records import Day, Household, Node

START, END = 360, 1440  # the grid: 06:00 to 24:00

OBJECTS = ("kettle", "fridge", "cupboard", "microwave")
HOME_PLACES = {"kettle": "counter#3", "fridge": "kitchen#2", "cupboard": "kitchen#2", "microwave": "counter#3"}
IN_USE = "in_use#4"


def _nodes() -> tuple[Node, ...]:
    nodes = [Node("home#1", "home", "Home", False, "home#1"), Node("kitchen#2", "kitchen", "Rooms", False, "home#1"),
             Node("counter#3", "counter", "Furniture", False, "kitchen#2"),
             Node("in_use#4", "in_use", "InUse", False, "kitchen#2")]
    nodes += [Node(f"{o}#{10 + i}", o, "placable_objects", True, HOME_PLACES[o]) for i, o in enumerate(OBJECTS)]
    return tuple(nodes)


@dataclass(frozen=True)
class _Block:
    activity: str
    start: float  # minute of the day
    uses: tuple[tuple[str, float], ...] = ()  # (object, minutes after the block starts)


def _clock_blocks(rng: random.Random, weekday: int) -> list[_Block]:
    """One day's schedule: (activity, start minute) with jitter; weekends sleep in and stay home."""
    j = lambda sd: rng.gauss(0, sd)  # noqa: E731
    workday = weekday < 5
    wake = (420 if workday else 480) + j(20)
    blocks = [_Block("sleeping", START), _Block("toileting", wake), _Block("grooming", wake + 8 + j(3)),
              _Block("breakfast", wake + 25 + j(5), (("kettle", 1.0), ("fridge", 2.5), ("cupboard", 4.0)))]
    if workday:
        leave = wake + 70 + j(10)
        blocks += [_Block("idle", blocks[-1].start + 20 + j(3)), _Block("leave_home", leave),
                   _Block("relax", 1050 + j(30)), _Block("meal_preparation", 1110 + j(15),
                                                         (("fridge", 2.0), ("cupboard", 6.0), ("microwave", 12.0))),
                   _Block("dinner", 1140 + j(10))]
    else:
        blocks += [_Block("relax", blocks[-1].start + 25 + j(5)), _Block("idle", 660 + j(30)),
                   _Block("meal_preparation", 740 + j(15), (("fridge", 1.5), ("microwave", 8.0))),
                   _Block("lunch", 760 + j(10)), _Block("relax", 800 + j(20)), _Block("work", 900 + j(40)),
                   _Block("meal_preparation", 1110 + j(15), (("fridge", 2.0), ("cupboard", 6.0))),
                   _Block("dinner", 1140 + j(10))]
    blocks += [_Block("washing_dishes", blocks[-1].start + 30 + j(5), (("cupboard", 3.0),)),
               _Block("relax", blocks[-1].start + 45 + j(8)), _Block("idle", 1290 + j(20)),
               _Block("sleeping", 1370 + j(20))]
    if rng.random() < 0.3:  # a drink in the afternoon, some days
        blocks.append(_Block("idle", 930 + j(30), (("kettle", 0.5), ("fridge", 1.0))))
    return sorted(blocks, key=lambda b: b.start)


def _unsettled(rng: random.Random, blocks: list[_Block], rate: float) -> list[_Block]:
    """Real days between the scheduled activities: the person drifts between ``idle`` and
    ``relax`` (and short chores) at random, about ``rate`` switches an hour while awake (none: 0)."""
    if rate <= 0:
        return list(blocks)
    out = list(blocks)
    for here, after in zip(blocks, blocks[1:] + [_Block("sleeping", END)]):
        if here.activity not in ("idle", "relax"):
            continue
        t = here.start
        while True:
            t += rng.expovariate(rate / 60)
            if t >= after.start - 5:
                break
            out.append(_Block(rng.choice(("idle", "relax", "relax", "idle", "grooming", "toileting")), t))
    return sorted(out, key=lambda b: b.start)


def _random_blocks(rng: random.Random, labels: tuple[str, ...]) -> list[_Block]:
    blocks, t = [], float(START)
    while t < END:
        blocks.append(_Block(rng.choice(labels), t, tuple((o, 1.0) for o in OBJECTS if rng.random() < 0.05)))
        t += rng.choice((10, 20, 30, 60, 90, 120, 180))
    return blocks


def _day(name: str, blocks: list[_Block], step: int, covering: bool = False) -> Day:
    """The blocks on the grid: each row takes the activity under way at its start; an object is in
    use in a row when one of its uses (a minute long) falls inside it, and at home otherwise; with
    ``covering``, each row also names the block covering most of its step, as importers do."""
    minutes = tuple(range(START, END + 1, step))
    starts = [b.start for b in blocks]
    activities = []
    for m in minutes:
        under_way = [b for b, s in zip(blocks, starts) if s <= m]
        activities.append(under_way[-1].activity if under_way else blocks[0].activity)
    uses = [(o, b.start + after) for b in blocks for o, after in b.uses]
    rows = []
    for m in minutes:
        rows.append(tuple(IN_USE if any(o == obj and m <= at < m + step for o, at in uses) else HOME_PLACES[obj]
                          for obj in OBJECTS))
    most = None
    if covering:
        ends = [*starts[1:], float("inf")]
        most = []
        for m, start_label in zip(minutes, activities):
            share: dict[str, float] = {}
            for b, s, e in zip(blocks, starts, ends):
                overlap = min(e, m + step) - max(s, m)
                if overlap > 0:
                    share[b.activity] = share.get(b.activity, 0.0) + overlap
            most.append(max(share, key=lambda a: (share[a], a == start_label, a)) if share else start_label)
    return Day(name, minutes, tuple(activities), tuple(rows), covering=None if most is None else tuple(most))


def _household(name: str, days: list[Day], test: int) -> Household:
    return Household(name, _nodes(), OBJECTS, tuple(days[:-test]), tuple(days[-test:]))


def clock_home(days: int = 75, test: int = 10, step: int = 10, seed: int = 0, drift: float = 0.0,
               dated: bool = False, covering: bool = False) -> Household:
    """A home whose routine is a clock (see the module doc); day i is weekday i % 7 (with
    ``dated``, named by its date from Monday 2024-01-01 on, as imported days are); ``drift``
    switches an hour between idle and relax make its quiet hours as unsettled as real ones."""
    rng = random.Random(seed)
    names = [(date(2024, 1, 1) + timedelta(days=i)).isoformat() if dated else f"day{i:03d}" for i in range(days)]
    return _household("Clock", [_day(name, _unsettled(rng, _clock_blocks(rng, i % 7), drift), step, covering)
                                for i, name in enumerate(names)], test)


def random_home(days: int = 75, test: int = 10, step: int = 10, seed: int = 0) -> Household:
    """A home with no routine (see the module doc)."""
    rng = random.Random(seed)
    labels = ("sleeping", "idle", "relax", "breakfast", "dinner", "grooming", "work", "leave_home")
    return _household("Random", [_day(f"day{i:03d}", _random_blocks(rng, labels), step) for i in range(days)], test)


def hourly_home(days: int = 40, test: int = 10, seed: int = 0) -> Household:
    """A home whose activity follows the hour whatever went before: every 10-minute step draws its
    activity afresh, half the time the hour's own (sleeping at night, breakfast at 7, lunch at 12,
    dinner at 18, one of four others in the other hours) and otherwise any of those four, so
    nothing persists from one step to the next. The time of day is all there is to learn;
    persistence, and a model of what follows what, learn noise."""
    rng = random.Random(seed)
    labels = ("idle", "relax", "grooming", "work")
    hours = {6: "sleeping", 7: "breakfast", 8: "grooming", 12: "lunch", 18: "dinner", 19: "relax", 22: "sleeping",
             23: "sleeping"}
    out = []
    for i in range(days):
        blocks = []
        for start in range(START, END + 1, 10):
            own = hours.get(start // 60, labels[(start // 60) % len(labels)])
            blocks.append(_Block(own if rng.random() < 0.5 else rng.choice(labels), float(start)))
        out.append(_day(f"day{i:03d}", blocks, 10))
    return _household("Hourly", out, test)


def weekly_home(days: int = 75, test: int = 10, seed: int = 0, dated: bool = True) -> Household:
    """A home whose week has two kinds of day that look the same until after breakfast (up near
    07:00): on weekdays then at work until about 17:00; at the weekend relaxing, out in the
    afternoon. Only the day of the week tells which follows breakfast. Named by date from Monday
    2024-01-01 on with ``dated``."""
    rng = random.Random(seed)
    out = []
    for i in range(days):
        j = lambda sd: rng.gauss(0, sd)  # noqa: E731
        blocks = [_Block("sleeping", START), _Block("breakfast", 420 + j(10), (("kettle", 2.0),))]
        if i % 7 < 5:
            blocks += [_Block("work", 450 + j(5)), _Block("relax", 1020 + j(20))]
        else:
            blocks += [_Block("relax", 450 + j(5)), _Block("outing", 780 + j(30)), _Block("relax", 1020 + j(20))]
        blocks.append(_Block("sleeping", 1380 + j(15)))
        name = (date(2024, 1, 1) + timedelta(days=i)).isoformat() if dated else f"day{i:03d}"
        out.append(_day(name, blocks, 10))
    return _household("Weekly", out, test)


def clocked_objects_home(days: int = 35, test: int = 7, seed: int = 0) -> Household:
    """A home whose objects follow the hour and the day of the week, not the activity: relaxing
    all afternoon (from about 13:00, every day alike), the kettle is taken at 15:00 on weekdays and
    the microwave at 17:00 at the weekend (each put back a step later, as a sensor reports a use).
    Named by date from Monday 2024-01-01 on: the clock and the day type tell the uses apart; the
    activity, and how long it has lasted, cannot."""
    rng = random.Random(seed)
    out = []
    for i in range(days):
        j = lambda sd: rng.gauss(0, sd)  # noqa: E731
        use = ("kettle", 900.0) if i % 7 < 5 else ("microwave", 1020.0)
        relax = 780 + j(20)
        blocks = [_Block("sleeping", START), _Block("breakfast", 450 + j(10)), _Block("idle", 500 + j(10)),
                  _Block("lunch", 730 + j(10)), _Block("relax", relax, ((use[0], use[1] + j(4) - relax),)),
                  _Block("dinner", 1140 + j(10)), _Block("sleeping", 1380 + j(15))]
        out.append(_day((date(2024, 1, 1) + timedelta(days=i)).isoformat(), blocks, 10))
    return _household("ClockedObjects", out, test)


def activity_objects_home(days: int = 30, test: int = 6, seed: int = 0) -> Household:
    """A home with no routine of the clock whose objects follow the activity: runs of random
    activities at random hours, and 25 minutes into every run of ``cooking`` (40 or 60 minutes
    long) the kettle is taken. How long the activity has lasted times the use; the hour cannot."""
    rng = random.Random(seed)
    labels = ("idle", "relax", "cooking", "grooming", "work")
    out = []
    for i in range(days):
        blocks, t = [], float(START)
        while t < END:
            label = rng.choice(labels)
            cooking = label == "cooking"
            blocks.append(_Block(label, t, (("kettle", 25.0),) if cooking else ()))
            t += rng.choice((40, 60)) if cooking else rng.choice((10, 20, 30, 60, 90))
        out.append(_day(f"day{i:03d}", blocks, 10))
    return _household("ActivityObjects", out, test)
