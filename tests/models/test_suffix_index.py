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
