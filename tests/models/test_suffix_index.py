"""The suffix automaton against brute-force n-gram counting on random sequences."""

import random
from collections import Counter

from globe.models.backoff import longest_distribution
from globe.models.suffix_index import SuffixIndex


def brute_longest(train, history, max_context):
    for k in range(min(len(history), max_context), -1, -1):
        ctx = tuple(history[len(history) - k:])
        counts = Counter(seq[j] for seq in train for j in range(k, len(seq)) if tuple(seq[j - k:j]) == ctx)
        if counts:
            total = sum(counts.values())
            return {w: c / total for w, c in counts.items()}
    return {}


def test_longest_context_matches_brute_force(seed):
    rng = random.Random(seed)
    for _ in range(20):
        alphabet = "abcd"[: rng.randint(2, 4)]
        train = ["".join(rng.choice(alphabet) for _ in range(rng.randint(1, 30))) for _ in range(rng.randint(1, 6))]
        index = SuffixIndex()
        for seq in train:
            index.add(seq)
        for _ in range(15):
            history = "".join(rng.choice(alphabet + "z") for _ in range(rng.randint(0, 12)))
            max_context = rng.randint(1, 10)
            state, matched = index.match(history)
            got = longest_distribution(index, state, matched, max_context)
            want = brute_longest(train, history, max_context)
            assert got.keys() == want.keys(), (train, history, max_context)
            assert all(abs(got[w] - want[w]) < 1e-12 for w in want)


def test_scan_equals_repeated_match(seed):
    rng = random.Random(seed + 1)
    index = SuffixIndex()
    for _ in range(5):
        index.add([rng.choice("xyz") for _ in range(40)])
    query = [rng.choice("xyzw") for _ in range(60)]
    assert list(index.scan(query)) == [index.match(query[: i + 1]) for i in range(len(query))]


def test_end_and_start_labels_are_never_predicted():
    index = SuffixIndex(never_predicted=["<s>"])
    index.add(["<s>", "a", "b"])
    assert set(index.successors(0)) == {"a", "b"}  # the root: not <s>, not </s>



def _state_of(index):
    """Every field an automaton is made of, as plain values."""
    fields = {name: list(getattr(index, name)) for name in ("_names", "_link", "_len", "_own", "_label1", "_target1",
                                                          "_start", "_labels", "_targets")}
    return fields | {"_ids": list(index._ids.items()), "_last": index._last,
                     "_more": {k: list(v.items()) for k, v in index._more.items()}}


def _built_both_ways(batches):
    """The same batches of sequences, through :meth:`SuffixIndex.add_all` and one by one in Python."""
    from globe.models import suffix_index

    together, one_by_one = SuffixIndex(), SuffixIndex()
    for batch in batches:
        together.add_all(batch)
        for seq in batch:
            one_by_one.add(seq)
        one_by_one.compact()
        assert _state_of(together) == _state_of(one_by_one)
    assert type(together._len) is type(one_by_one._len) and together._own.typecode == one_by_one._own.typecode == "b"
    return together, one_by_one, suffix_index._native is not None


def test_add_all_builds_the_same_automaton(seed):
    """add_all (compiled where the install built it) appends, clones and redirects exactly as the
    Python loop: every array, the label numbering and each state's transition order are equal,
    from an empty index and from one already compacted (the service learning a day)."""
    rng = random.Random(seed + 2)
    for _ in range(60):
        alphabet = "abcdefg"[: rng.randint(1, 7)]
        seqs = [[rng.choice(alphabet) for _ in range(rng.randint(0, 50))] for _ in range(rng.randint(1, 8))]
        if rng.random() < 0.3:  # long runs, as activities have
            seqs = [[c for c in seq for _ in range(rng.randint(1, 9))] for seq in seqs]
        cut = rng.randint(0, len(seqs))
        together, one_by_one, _ = _built_both_ways([seqs[:cut], seqs[cut:], []])
        query = [rng.choice(alphabet + "z") for _ in range(30)]
        assert list(together.scan(query)) == list(one_by_one.scan(query))
        assert [together.successors(s) for s in range(len(together._len))] == \
            [one_by_one.successors(s) for s in range(len(one_by_one._len))]


def test_add_all_on_homer_activities_and_object_runs(households):
    """The automata of the activity and object models on HOMER+ days, both ways (compiled, where
    the install built it)."""
    from globe.assembly import training_sequences

    for h in households.values():
        seqs = training_sequences(h, h.train, "previous")
        _built_both_ways([[("<s>", *d) for d in seqs.activities[:40]], [("<s>", *d) for d in seqs.activities[40:]]])
        by_activity: dict[str, list] = {}
        for activity, objects in seqs.runs:
            by_activity.setdefault(activity, []).append(objects)
        for runs in by_activity.values():
            _built_both_ways([runs])


def test_add_all_refuses_what_it_cannot_number():
    import pytest

    index = SuffixIndex()
    with pytest.raises(TypeError):
        index.add_all([["a", ["unhashable"]]])


def test_the_compiled_parts_are_built_where_ci_runs():
    """CI installs with a C compiler (llama.cpp needs one), so it must test the compiled paths;
    elsewhere the Python loop is a correct fallback and this only reports which one runs."""
    import os

    from globe.models import activity_filter, forecast, suffix_index

    if os.environ.get("CI") == "true":
        assert suffix_index._native is not None, "globe.models._suffix_automaton was not compiled"
        assert activity_filter._native is not None, "globe.models._filter_core was not compiled (or refused to load)"
        assert forecast._native is not None, "globe.models._forecast_core was not compiled (or refused to load)"
    assert suffix_index._native is None or callable(suffix_index._native.extend)
    assert activity_filter._native is None or callable(activity_filter._native.Core)
    assert forecast._native is None or callable(forecast._native.Paths)


def test_a_damaged_index_is_an_error_not_a_bad_read():
    """The compiled path checks every state number it will follow before it reads any."""
    from array import array

    import pytest

    from globe.models import suffix_index

    if suffix_index._native is None:
        pytest.skip("globe.models._suffix_automaton was not compiled in this install")
    index = SuffixIndex()
    index.add_all([list("abcab"), list("bca")])
    index._target1 = array("i", [t + 10_000 if t >= 0 else t for t in index._target1])
    with pytest.raises(ValueError, match="damaged"):
        index.add_all([list("ab")])
