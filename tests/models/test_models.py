"""Contract tests for both counting models (scikit-learn-style estimator checks)."""

import math
import random
from array import array

import pytest

from globe.data.records import Day
from globe.errors import ConfigError, ModelFileError, NotFittedError
from globe.models.activity import ActivityModel
from globe.models.clock import ClockModel
from globe.models.io import load_model, save_model
from globe.models.objects import ObjectModel
from globe.models.routine import RoutineModel
from globe.models.suffix_index import END, SuffixIndex
from globe.sequences.packed_days import PackedDays

DAYS = [("sleep", "wake", "eat", "eat", "work"), ("sleep", "wake", "eat", "work", "work"),
        ("sleep", "sleep", "wake", "eat", "tv")]
RUNS = [("eat", ("bowl", "milk", "spoon")), ("eat", ("bowl", "cereal")), ("work", ("laptop",)),
        ("eat", ("plate",)), ("work", ())]


def test_longest_context_and_backoff_by_hand():
    m = ActivityModel().fit(DAYS)
    # <day> sleep wake -> eat twice (days 1, 2); <day> sleep sleep wake -> eat once
    assert m.predict_proba(["sleep", "wake"]) == {"eat": 1.0}
    # "wake eat eat" never seen; "eat eat" seen once, followed by work
    assert m.predict_proba(["sleep", "wake", "eat", "eat"]) == {"work": 1.0}
    # "eat" followed by: eat, work (day 1), work (day 2), tv (day 3) but the longest context
    # "<day> sleep wake eat" is followed by eat (d1) and work (d2)
    assert m.predict_proba(["sleep", "wake", "eat"]) == {"eat": 0.5, "work": 0.5}
    # an unseen activity backs off to the unigram of all training labels (15 labels)
    assert m.predict_proba(["dance"])["sleep"] == pytest.approx(4 / 15)


def test_max_order_limits_the_context():
    m = ActivityModel(max_order=2).fit(DAYS)  # bigram: context is the last activity only
    # after "eat": eat (1), work (2), tv (1)
    assert m.predict_proba(["sleep", "wake", "eat"]) == {"eat": 0.25, "work": 0.5, "tv": 0.25}


def test_ties_break_by_training_frequency_then_name():
    m = ActivityModel().fit(DAYS)
    # eat (5 occurrences in training) beats work (3) at 0.5 / 0.5
    assert m.predict(["sleep", "wake", "eat"]) == "eat"


def test_object_model_restricted_to_the_activity_and_backs_off():
    m = ObjectModel().fit(RUNS)
    assert m.candidates("eat") == ("bowl", "cereal", "milk", "plate", "spoon")
    assert m.predict_proba("eat", ("bowl",)) == {"milk": 0.5, "cereal": 0.5}
    # unseen context -> P(o | eat): bowl 2, milk 1, spoon 1, cereal 1, plate 1 of 6
    assert m.predict_proba("eat", ("laptop",))["bowl"] == pytest.approx(2 / 6)
    assert m.predict_proba("dance", ()) == {}
    assert m.predict("dance") is None


def test_recent_runs_follow_new_runs_and_new_fits():
    """The person's recent runs are remembered per activity; learning or refitting must show."""
    m = ObjectModel().fit([("eat", ("bowl",)), ("eat", ("plate",)), ("work", ("laptop",))])
    assert m.recent_runs("eat", 2) == (("bowl",), ("plate",))
    m.partial_fit([("eat", ("cup",))])
    assert m.recent_runs("eat", 2) == (("plate",), ("cup",))
    m.fit([("eat", ("spoon",)), ("eat", ("fork",)), ("work", ("pen",))])  # as many runs as the first fit
    assert m.recent_runs("eat", 2) == (("spoon",), ("fork",))


def test_remembered_distributions_follow_learning():
    """Distributions are memoised per context; a new run or a new fit must show in the answer."""
    m = ObjectModel().fit([("eat", ("bowl",)), ("eat", ("plate",))])
    assert m.predict_proba("eat", ()) == {"bowl": pytest.approx(0.5), "plate": pytest.approx(0.5)}
    m.partial_fit([("eat", ("bowl",))])
    assert m.predict_proba("eat", ()) == {"bowl": pytest.approx(2 / 3), "plate": pytest.approx(1 / 3)}
    m.fit([("eat", ("cup",))])
    assert m.predict_proba("eat", ()) == {"cup": pytest.approx(1.0)}


def test_run_start_token_conditions_the_first_object():
    m = ObjectModel(run_start_token=True).fit(RUNS)
    assert m.predict_proba("eat", ()) == {"bowl": pytest.approx(2 / 3), "plate": pytest.approx(1 / 3)}


MODELS = [
    pytest.param(lambda: ActivityModel(), DAYS, lambda m: m.predict_proba(["sleep", "wake"]), id="activity-longest"),
    pytest.param(lambda: ActivityModel(estimator="witten_bell", max_order=3, time_weight=1.0), DAYS,
                 lambda m: m.predict_proba(["sleep", "wake", "eat"]), id="activity-wb-time"),
    pytest.param(lambda: RoutineModel(order=2, time_weight=1.0), DAYS,
                 lambda m: m.predict_proba(["sleep", "wake", "eat"]), id="activity-routine"),
    pytest.param(lambda: ClockModel(slot_minutes=20, shrinkage=2.0), DAYS,
                 lambda m: m.predict_proba(["sleep", "wake", "eat"]), id="activity-clock"),
    pytest.param(lambda: ObjectModel(), RUNS, lambda m: m.predict_proba("eat", ("bowl",)), id="object-longest"),
    pytest.param(lambda: ObjectModel(estimator="witten_bell", run_start_token=True), RUNS,
                 lambda m: m.predict_proba("eat", ("bowl",)), id="object-wb"),
]


@pytest.mark.parametrize("make, data, query", MODELS)
def test_contract(make, data, query, tmp_path):
    with pytest.raises(NotFittedError, match="not fitted yet"):
        query(make())
    model = make().fit(data)
    dist = query(model)
    assert math.isclose(sum(dist.values()), 1.0)
    assert query(model) == dist  # deterministic
    pieces = make().partial_fit(data[:1]).partial_fit(data[1:])
    assert query(pieces) == dist
    save_model(model, tmp_path / "m.json")
    assert query(load_model(tmp_path / "m.json")) == dist


def test_scan_equals_predict_proba(fitted, households):
    model = fitted["A"].activity
    day = households["A"].test[0].activities
    scanned = model.scan_proba(day)
    for t in (0, 1, 17, 60, 108):
        assert scanned[t] == model.predict_proba(day[:t])


def test_bad_parameters_are_rejected_at_fit():
    with pytest.raises(ConfigError, match=r"estimator='best'; expected one of 'longest', 'witten_bell'"):
        ActivityModel(estimator="best").fit(DAYS)


def test_model_file_errors(tmp_path):
    bad = tmp_path / "m.json"
    bad.write_text('{"format": "globe-model", "version": 99, "kind": "activity"}')
    with pytest.raises(ModelFileError, match="format version 99"):
        load_model(bad)
    with pytest.raises(ModelFileError, match="model file not found"):
        load_model(tmp_path / "none.json")


def test_confidence_is_the_top_probability():
    m = ActivityModel().fit(DAYS)
    assert m.confidence(["sleep", "wake", "eat"]) == 0.5
    om = ObjectModel().fit(RUNS)
    assert om.confidence("eat", ("bowl",)) == 0.5
    assert om.confidence("dance") == 0.0


class DictSuffixIndex:
    """The suffix automaton as it was before it was compacted (one dict of transitions per
    state): the reference the compact :class:`SuffixIndex` must answer exactly like."""

    def __init__(self, never_predicted=()):
        self.skip = set(never_predicted) | {END}
        self.next, self.link, self.len, self.own, self.last = [{}], [-1], [0], [0], 0

    def add(self, sequence):
        nxt, link, length, own, last = self.next, self.link, self.len, self.own, self.last
        for c in (*sequence, END):
            cur = len(length)
            nxt.append({}), length.append(length[last] + 1), link.append(0), own.append(1)
            p = last
            while p != -1 and c not in nxt[p]:
                nxt[p][c] = cur
                p = link[p]
            if p != -1:
                q = nxt[p][c]
                if length[p] + 1 == length[q]:
                    link[cur] = q
                else:
                    clone = len(length)
                    nxt.append(nxt[q].copy()), length.append(length[p] + 1), link.append(link[q]), own.append(0)
                    while p != -1 and nxt[p].get(c) == q:
                        nxt[p][c] = clone
                        p = link[p]
                    link[q] = link[cur] = clone
            last = cur
        self.last = last

    def successors(self, state):
        counts = list(self.own)
        for v in sorted(range(1, len(self.len)), key=self.len.__getitem__, reverse=True):
            counts[self.link[v]] += counts[v]
        return {c: counts[t] for c, t in self.next[state].items() if c not in self.skip}

    def match(self, history):
        state, matched = 0, 0
        for label in history:
            while state != -1 and label not in self.next[state]:
                state = self.link[state]
            state, matched = (0, 0) if state == -1 else (self.next[state][label], min(matched, self.len[state]) + 1)
        return state, matched


def test_compact_suffix_index_answers_exactly_like_one_dict_per_state(seed):
    """Same states, links, counts and successor order (distributions are summed in that order),
    whether sequences are added one batch at a time or several at once."""
    rng = random.Random(seed)
    for _ in range(200):
        alphabet = [f"a{i}" for i in range(rng.randint(1, 9))]
        ref, got = DictSuffixIndex(["a0"]), SuffixIndex(["a0"])
        for _ in range(rng.randint(1, 5)):
            batch = [[rng.choice(alphabet) for _ in range(rng.randint(0, 30))] for _ in range(rng.randint(1, 3))]
            for seq in batch:
                ref.add(seq)
            got.add_all(batch)
        states = len(ref.len)
        assert [got.length(s) for s in range(states)] == ref.len and [got.link(s) for s in range(states)] == ref.link
        for s in range(states):
            assert list(got.successors(s).items()) == list(ref.successors(s).items())
        for _ in range(20):
            history = [rng.choice([*alphabet, "unseen"]) for _ in range(rng.randint(0, 40))]
            assert got.match(history) == ref.match(history)
            assert list(got.scan(history)) == [ref.match(history[: i + 1]) for i in range(len(history))]


def test_fitted_models_keep_their_automata_compact():
    """Compaction is what makes a household small: after a fit nothing is left in dicts."""
    activity = ActivityModel().fit(DAYS)
    objects = ObjectModel().fit(RUNS)
    for index in (activity.index_, *objects.indexes_.values()):
        assert len(index._start) == len(index._len) + 1 and isinstance(index._label1, array)
    activity.partial_fit([("sleep", "tv")])
    # "<day> sleep" was followed by wake (days 1, 2), sleep (day 3) and tv (the day learned)
    assert activity.predict_proba(["sleep"]) == {"wake": 0.5, "sleep": 0.25, "tv": 0.25}


def test_packed_days_give_back_the_days_packed(seed):
    """What the movement model keeps instead of its training days must read back as the same
    days: every field, in order, also for rows shared between days and for negative indexes."""
    rng = random.Random(seed)
    places = ["table#1", "shelf#2", "sink#3", "bed#4"]
    days = []
    for d in range(6):
        steps = rng.randint(1, 12)
        minutes = tuple(sorted(rng.sample(range(360, 1440), steps)))
        rows = [tuple(rng.choice(places[:2]) for _ in range(3)) for _ in range(steps)]
        days.append(Day(f"train/{d:03d}", minutes, tuple(rng.choice(["eat", "sleep", "tv"]) for _ in range(steps)),
                        tuple(rows), f"upload-{d}"))
    packed = PackedDays(days)
    assert len(packed) == len(days) and list(packed) == days
    assert packed[-1] == days[-1] and packed[1:3] == tuple(days[1:3])
    with pytest.raises(IndexError):
        packed[len(days)]
    assert list(PackedDays([])) == []
    # extending a packing gives back the same days as packing them all at once, one day or several at a time
    grown = PackedDays(days[:2])
    for k in (3, 4, 6):
        grown = grown.extended(days[len(grown):k])
    assert list(grown) == days and grown.offsets == packed.offsets and list(PackedDays().extended(days)) == days
    # the numbered view gives back every step's row, day by day
    steps, table, labels = packed.coded_rows(3)
    for i, day in enumerate(days):
        lo, hi = packed.offsets[i], packed.offsets[i + 1]
        assert [tuple(labels[x] for x in table[r]) for r in steps[lo:hi]] == list(day.locations)
    with pytest.raises(ValueError):
        packed.coded_rows(2)
