"""Uploaded maps and day logs follow exactly the rules of files on disk: the fast path of
``parse_day`` gives the data layer's result, and its messages for rows it does not accept."""

import random

import pytest

from globe.data.csv_logs import format_day, parse_day_text
from globe.errors import DataError
from globe.service.client import household_payload
from globe.service.upload import DayParser, household_from, parse_day, parse_nodes


def outcome(parse, *args):
    try:
        day, lines = parse(*args)
        return ("ok", day.minutes, day.activities, day.locations, lines)
    except DataError as err:
        return ("error", str(err))


def test_the_fast_path_equals_the_data_layer_on_every_homer_day(households):
    for h in households.values():
        objects, locations = h.objects, frozenset(n.node for n in h.nodes)
        owners = {n.cls: n.node for n in h.nodes if n.movable}
        for d in h.train + h.test:
            text = format_day(d, objects)
            assert outcome(parse_day, text, objects, locations, "d", owners) == \
                outcome(parse_day_text, text, objects, locations, "d", "d", owners)


def test_broken_rows_get_the_data_layers_messages(households, seed):
    rng = random.Random(seed)
    h = households["A"]
    objects, locations = h.objects, frozenset(n.node for n in h.nodes)
    owners = {n.cls: n.node for n in h.nodes if n.movable}
    lines = format_day(h.train[0], objects).split("\n")
    owned = next(iter(owners.values()))
    edits = [lambda c: c.__setitem__(0, "abc"), lambda c: c.__setitem__(0, "9999"), lambda c: c.__setitem__(0, "１２"),
             lambda c: c.__setitem__(1, ""), lambda c: c.__setitem__(1, "idle\x07"),
             lambda c: c.__setitem__(2, "moon#1"), lambda c: c.pop(), lambda c: c.append("x"),
             lambda c: c.__setitem__(2, f" {c[2]}\t"),
             lambda c: c.__setitem__(objects.index(next(o for o, lab in owners.items() if lab == owned)) + 2, owned)]
    for edit in edits:
        for _ in range(3):
            k = rng.randrange(1, len(lines) - 1)
            cells = lines[k].split(",")
            edit(cells)
            text = "\n".join(lines[:k] + [",".join(cells)] + lines[k + 1:])
            assert outcome(parse_day, text, objects, locations, "d", owners) == \
                outcome(parse_day_text, text, objects, locations, "d", "d", owners), (edit, k)


def test_one_parser_for_many_days_answers_like_the_data_layer_on_each(households, seed):
    """A DayParser remembers the rows, minutes and activities it accepted in earlier days: that
    must change no later day's result or message (broken days among good ones, any order)."""
    rng = random.Random(seed)
    h = households["C"]
    objects, locations = h.objects, frozenset(n.node for n in h.nodes)
    owners = {n.cls: n.node for n in h.nodes if n.movable}
    texts = [format_day(d, objects) for d in h.train[:6]]
    broken = []
    for text in texts[:4]:
        lines = text.split("\n")
        k = rng.randrange(2, len(lines) - 2)
        cells = lines[k].split(",")
        earlier = lines[k - 1].split(",")[0]  # a minute that does not increase
        for col, value in ((3, "moon#1"), (0, earlier), (1, "idle\x07"), (4, f" {cells[4]}\t")):
            changed = list(cells)
            changed[col] = value
            broken.append("\n".join(lines[:k] + [",".join(changed)] + lines[k + 1:]))
    parser = DayParser(objects, locations, owners)
    for text in rng.sample(texts + broken, len(texts + broken)) + texts:
        assert outcome(parser.parse, text, "d") == outcome(parse_day_text, text, objects, locations, "d", "d", owners)


def test_maps_follow_the_map_rules(households):
    nodes = household_payload(households["B"])["nodes"]
    assert parse_nodes(nodes) == households["B"].nodes
    with pytest.raises(DataError) as err:
        parse_nodes(nodes + [dict(nodes[0])])
    assert err.value.field == f"nodes[{len(nodes)}].node"
    k = next(i for i, n in enumerate(nodes) if n["movable"])
    with pytest.raises(DataError) as err:  # an object inside itself
        parse_nodes([dict(n, start_location=n["node"]) if i == k else n for i, n in enumerate(nodes)])
    assert err.value.field == f"nodes[{k}].start_location"
    h = household_from("B", parse_nodes(nodes), household_payload(households["B"])["days"])
    assert [d.locations for d in h.train] == [d.locations for d in households["B"].train]


@pytest.mark.parametrize("where", ["after the header", "inside", "at the end", "two at the end", "only newlines"])
def test_blank_lines_get_the_data_layers_answer(households, where):
    h = households["B"]
    objects, locations = h.objects, frozenset(n.node for n in h.nodes)
    owners = {n.cls: n.node for n in h.nodes if n.movable}
    lines = format_day(h.train[1], objects).rstrip("\n").split("\n")
    text = {"after the header": "\n".join([lines[0], "", *lines[1:]]),
            "inside": "\n".join([*lines[:5], "", *lines[5:]]),
            "at the end": "\n".join(lines) + "\n\n", "two at the end": "\n".join(lines) + "\n\n\n",
            "only newlines": lines[0] + "\n\n\n"}[where]
    assert outcome(parse_day, text, objects, locations, "d", owners) == \
        outcome(parse_day_text, text, objects, locations, "d", "d", owners)


def test_an_activity_that_is_not_valid_unicode_is_refused_by_name(households):
    """JSON can carry a lone surrogate ("\\ud800") that no UTF-8 file can: such an activity is
    refused like a control character, naming the day, the line and the field, instead of failing
    later when the day is stored."""
    h = households["A"]
    payload = household_payload(h)
    lines = payload["days"][1].split("\n")
    minute, _, rest = lines[3].split(",", 2)
    lines[3] = f"{minute},cook\ud800,{rest}"
    days = [payload["days"][0], "\n".join(lines)]
    with pytest.raises(DataError) as err:
        household_from("A", parse_nodes(payload["nodes"]), days)
    assert (err.value.source, err.value.line, err.value.field) == ("days[1]", 4, "activity")
    assert "lone surrogate" in str(err.value)
