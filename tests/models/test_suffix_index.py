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
        index.add_all(train)
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
    index.add_all([[rng.choice("xyz") for _ in range(40)] for _ in range(5)])
    query = [rng.choice("xyzw") for _ in range(60)]
    assert list(index.scan(query)) == [index.match(query[: i + 1]) for i in range(len(query))]


def test_end_and_start_labels_are_never_predicted():
    index = SuffixIndex(never_predicted=["<s>"])
    index.add_all([["<s>", "a", "b"]])
    assert set(index.successors(0)) == {"a", "b"}  # the root: not <s>, not </s>



def test_growing_an_index_answers_as_building_it_at_once(seed):
    """The service learns a day at a time: an automaton grown batch by batch answers every query
    as one built from all the sequences at once (the same counts, the same orders)."""
    rng = random.Random(seed + 2)
    for _ in range(40):
        alphabet = "abcdefg"[: rng.randint(1, 7)]
        seqs = [[rng.choice(alphabet) for _ in range(rng.randint(0, 50))] for _ in range(rng.randint(1, 8))]
        if rng.random() < 0.3:  # long runs, as activities have
            seqs = [[c for c in seq for _ in range(rng.randint(1, 9))] for seq in seqs]
        cut = rng.randint(0, len(seqs))
        grown, whole = SuffixIndex(), SuffixIndex()
        grown.add_all(seqs[:cut])
        grown.add_all(seqs[cut:])
        grown.add_all([])
        whole.add_all(seqs)
        assert len(grown) == len(whole)
        query = [rng.choice(alphabet + "z") for _ in range(30)]
        assert list(grown.scan(query)) == list(whole.scan(query))
        assert [grown.successors(s) for s in range(len(grown))] == [whole.successors(s) for s in range(len(whole))]


def test_add_all_refuses_what_it_cannot_number():
    import pytest

    index = SuffixIndex()
    with pytest.raises(TypeError):
        index.add_all([["a", ["unhashable"]]])


def test_the_compiled_parts_are_built():
    """Each compiled kernel is the only implementation of what it does: the install builds it."""
    from globe.inference import _beam, _propagate
    from globe.models import _suffix_automaton

    assert callable(_suffix_automaton.extend) and callable(_beam.select) and callable(_propagate.level)


def test_a_damaged_index_is_an_error_not_a_bad_read():
    """The compiled path checks every state number it will follow before it reads any."""
    from array import array

    import pytest

    index = SuffixIndex()
    index.add_all([list("abcab"), list("bca")])
    index._target1 = array("i", [t + 10_000 if t >= 0 else t for t in index._target1])
    with pytest.raises(ValueError, match="damaged"):
        index.add_all([list("ab")])
