import pytest

from globe.data.records import Day, Household
from globe.sequences.movements import extract_movements, moved_steps
from globe.sequences.runs import activity_runs, run_bounds, run_objects, training_sequences

OBJECTS = ("cup", "plate", "book")
# step:        0            1            2            3           4
ACTS = ("idle", "breakfast", "breakfast", "idle", "reading")
LOCS = (
    ("cupboard#1", "cupboard#1", "shelf#2"),
    ("cupboard#1", "cupboard#1", "shelf#2"),
    ("table#3", "table#3", "shelf#2"),  # cup and plate move at step 2
    ("sink#4", "table#3", "shelf#2"),  # cup moves at step 3
    ("sink#4", "table#3", "sofa#5"),  # book moves at step 4
)
DAY = Day("toy", (360, 370, 380, 390, 400), ACTS, LOCS)


def test_movements_in_column_order_with_previous_alignment():
    events = extract_movements(DAY, OBJECTS, "previous")
    assert [(e.step, e.obj, e.activity) for e in events] == [
        (2, "cup", "breakfast"), (2, "plate", "breakfast"), (3, "cup", "breakfast"), (4, "book", "idle")]
    assert events[0].source == "cupboard#1" and events[0].target == "table#3"


@pytest.mark.parametrize("alignment, expected", [
    ("current", ["breakfast", "breakfast", "idle", "reading"]),
    ("hybrid", ["breakfast", "breakfast", "breakfast", "reading"]),  # step 4: t-1 is idle -> t
])
def test_alignment_options(alignment, expected):
    assert [e.activity for e in extract_movements(DAY, OBJECTS, alignment)] == expected


def test_runs_group_events_by_activity_run():
    assert run_bounds(ACTS) == [(0, 0), (1, 2), (3, 3), (4, 4)]
    runs = activity_runs(DAY, OBJECTS, "previous")
    assert [(r.activity, r.objects) for r in runs] == [
        ("idle", ()), ("breakfast", ("cup", "plate", "cup")), ("idle", ("book",)), ("reading", ())]
    home = Household("toy", (), OBJECTS, (DAY,), ())
    seqs = training_sequences(home, [DAY], "previous")
    assert seqs.activities == [ACTS]
    assert seqs.runs == [("idle", ()), ("breakfast", ("cup", "plate", "cup")), ("idle", ("book",)), ("reading", ())]


def test_unknown_alignment_is_rejected():
    with pytest.raises(ValueError, match="expected one of previous, current, hybrid"):
        extract_movements(DAY, OBJECTS, "later")  # type: ignore[arg-type]


def test_moved_steps_list_what_moved_in_column_order():
    assert moved_steps(DAY, OBJECTS) == [(2, ("cup", "plate")), (3, ("cup",)), (4, ("book",))]


@pytest.mark.parametrize("alignment", ["previous", "current", "hybrid"])
def test_run_objects_are_the_objects_of_activity_runs(alignment):
    expected = [(r.activity, r.objects) for r in activity_runs(DAY, OBJECTS, alignment)]
    assert run_objects(DAY, OBJECTS, alignment) == expected
    assert run_objects(DAY, OBJECTS, alignment, moved_steps(DAY, OBJECTS)) == expected
    home = Household("toy", (), OBJECTS, (DAY, DAY), ())
    seqs = training_sequences(home, [DAY, DAY], alignment)
    assert seqs.runs == expected * 2 and seqs.moves == [moved_steps(DAY, OBJECTS)] * 2


def test_moved_steps_memo_answers_as_without_it_even_for_days_built_on_the_fly():
    """The memo is keyed by the row objects' ids; it keeps the rows, so a day freed after its
    call cannot lend its ids to another day's different rows."""
    def fresh_day(shift: int) -> Day:  # new row tuples on every call
        rows = [tuple(f"{loc}{(i + shift) % 3 if k == shift % 3 else ''}" for k, loc in enumerate(row))
                for i, row in enumerate(LOCS)]
        return Day(f"d{shift}", DAY.minutes, ACTS, tuple(rows))

    memo: dict = {}
    for shift in range(30):
        assert moved_steps(fresh_day(shift), OBJECTS, memo) == moved_steps(fresh_day(shift), OBJECTS)


def test_most_credits_the_activity_covering_most_of_the_step():
    """Step 3 is idle at its start but reading, which begins during it, covers most of it: the cup
    used then joins reading; steps 2 and 4 are covered mostly by their own start labels; a
    covering activity that is neither (a short one the grid never shows) leaves the start label;
    without covering, 'most' is 'current'."""
    late = Day("toy", DAY.minutes, ACTS, LOCS, covering=("idle", "breakfast", "breakfast", "reading", "reading"))
    assert [(e.step, e.obj, e.activity_step, e.activity) for e in extract_movements(late, OBJECTS, "most")] == [
        (2, "cup", 2, "breakfast"), (2, "plate", 2, "breakfast"), (3, "cup", 4, "reading"), (4, "book", 4, "reading")]
    short = Day("toy", DAY.minutes, ACTS, LOCS, covering=("idle", "breakfast", "breakfast", "tea", "reading"))
    assert [e.activity_step for e in extract_movements(short, OBJECTS, "most")] == [2, 2, 3, 4]
    assert extract_movements(DAY, OBJECTS, "most") == extract_movements(DAY, OBJECTS, "current")
    assert run_objects(late, OBJECTS, "most") == [(r.activity, r.objects) for r in activity_runs(late, OBJECTS, "most")]
    assert run_objects(late, OBJECTS, "most")[-1] == ("reading", ("cup", "book"))
