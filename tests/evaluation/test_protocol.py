import csv

import pytest

from globe.data.records import Day, Household, Node
from globe.evaluation.experiments import run_methods, table1_rows
from globe.evaluation.metrics import f1
from globe.evaluation.protocol import evaluate_days
from globe.models.activity import ActivityModel
from globe.models.objects import ObjectModel
from globe.reasoning.choice import ObjectChooser
from globe.sequences.runs import activity_runs

OBJECTS = ("cup", "book")
NODES = tuple(Node(n, n.split("#")[0], "Furniture", False, "home#-1") for n in ("home#-1", "shelf#1", "table#2")) + (
    Node("cup#10", "cup", "placable_objects", True, "shelf#1"),
    Node("book#11", "book", "placable_objects", True, "shelf#1"))


def day(name, acts, moves):
    """moves: {step: {obj: loc}} applied from that step on."""
    state = {"cup": "shelf#1", "book": "shelf#1"}
    locs = []
    for t in range(len(acts)):
        state.update(moves.get(t, {}))
        locs.append(tuple(state[o] for o in OBJECTS))
    return Day(name, tuple(360 + 10 * t for t in range(len(acts))), tuple(acts), tuple(locs))


TRAIN = [day(f"train/{i}", ["idle", "tea", "tea", "read", "read"], {2: {"cup": "table#2"}, 4: {"book": "table#2"}})
         for i in range(3)]
TEST = [day("test/0", ["idle", "tea", "read", "read", "read"], {2: {"cup": "table#2"}, 3: {"book": "table#2"}})]
HOME = Household("T", NODES, OBJECTS, tuple(TRAIN), tuple(TEST))


def test_protocol_by_hand():
    am = ActivityModel().fit([d.activities for d in TRAIN])
    om = ObjectModel().fit([(r.activity, r.objects) for d in TRAIN for r in activity_runs(d, OBJECTS)])
    ev = evaluate_days(HOME, HOME.test, am, ObjectChooser(om))
    # steps 1..4; the model predicts tea, tea, read, read; truth tea, read, read, read
    assert [(r.step, r.true, r.predicted) for r in ev.activity] == [
        (1, "tea", "tea"), (2, "read", "tea"), (3, "read", "read"), (4, "read", "read")]
    assert [r.is_change for r in ev.activity] == [True, True, False, False]
    # cup moves at step 2 -> activity step 1 (tea, predicted tea); book at step 3 -> step 2
    # (true read, predicted tea: O(tea) = {cup}, context reset)
    assert [(r.true_activity, r.predicted_activity, r.true, r.predicted) for r in ev.objects] == [
        ("tea", "tea", "cup", "cup"), ("read", "tea", "book", "cup")]
    oracle = evaluate_days(HOME, HOME.test, am, ObjectChooser(om), oracle=True)
    assert [r.predicted for r in oracle.objects] == ["cup", "book"]


def test_f1_uses_sklearn_weighted_average():
    # per class: a: P=1/2, R=1 -> F=2/3 (support 1); b: P=1, R=1/2 -> F=2/3 (support 2)
    assert f1(["a", "b", "b"], ["a", "a", "b"]) == pytest.approx(2 / 3)
    assert f1(["a", "b", "b"], ["a", "a", "b"], "micro") == pytest.approx(2 / 3)


@pytest.fixture(scope="module")
def homer_runs(households, config):
    return run_methods(config, list(households.values()), ["persistence", "ngram"], None)


def test_persistence_matches_the_planning_measurement(homer_runs):
    # measurements.md: persistence weighted activity F1 0.759 (A), 0.811 (B), 0.763 (C)
    got = {r.household: f1([x.true for x in r.evaluation.activity], [x.predicted for x in r.evaluation.activity])
           for r in homer_runs if r.method == "persistence"}
    assert got == pytest.approx({"A": 0.759, "B": 0.811, "C": 0.763}, abs=0.0015)


def test_ngram_row_lands_near_the_paper(homer_runs):
    rows = table1_rows(homer_runs)
    mean = next(r for r in rows if r["method"] == "ngram" and r["household"] == "mean" and r["average"] == "weighted")
    # published n-gram Markov row: 0.79 / 0.64 / 0.72
    assert mean["activity_f1"] == pytest.approx(0.79, abs=0.03)
    assert mean["object_f1"] == pytest.approx(0.64, abs=0.03)
    assert mean["mean_f1"] == pytest.approx(0.72, abs=0.02)
    events = sum(len(r.evaluation.objects) for r in homer_runs if r.method == "ngram")
    assert events == 1682  # every movement event of the 30 test days is scored once


def test_table1_rows_have_the_documented_columns(homer_runs, tmp_path):
    from globe.evaluation.report import write_csv

    rows = table1_rows(homer_runs)
    write_csv(tmp_path / "table1.csv", rows)
    with (tmp_path / "table1.csv").open() as fh:
        reader = csv.DictReader(fh)
        assert reader.fieldnames == ["method", "household", "average", "activity_f1", "object_f1", "mean_f1",
                                     "n_households", "n_households_object"]
        got = list(reader)
    assert {(r["method"], r["household"], r["average"]) for r in got} == {
        (m, h, a) for m in ("persistence", "ngram") for h in ("A", "B", "C", "mean")
        for a in ("weighted", "micro", "macro")}


def test_rankings_shared_between_choosers_give_the_same_records(households, fitted):
    """Gate candidates of a cross-validation fold share each event's n-gram ranking."""
    from globe.reasoning.backends.base import Choice, LLMBackend
    from globe.reasoning.gate import UncertaintyGate

    class Last(LLMBackend):
        name = "last"

        def choose(self, context, candidates):
            return Choice(sorted(candidates)[-1], {c: float(i) for i, c in enumerate(sorted(candidates))})

    h, models = households["B"], fitted["B"]
    days = h.test[:3]
    plain = ObjectChooser(models.objects)
    gate = UncertaintyGate(models.objects, Last(), threshold=0.6)
    alone = [evaluate_days(h, days, models.activity, c) for c in (plain, gate)]
    shared: dict = {}
    together = [evaluate_days(h, days, models.activity, c, rankings=shared) for c in (plain, gate)]
    assert len(shared) == len(alone[0].objects) > 0  # one ranking per movement event, computed once
    for a, b in zip(alone, together):
        assert [(r.day, r.step, r.predicted, r.confidence, r.asked) for r in a.objects] == \
               [(r.day, r.step, r.predicted, r.confidence, r.asked) for r in b.objects]
    assert any(r.asked for r in together[1].objects)  # the gate did ask, on shared rankings


def test_llm_time_counts_the_batched_scoring_not_only_the_cache_reads():
    """With a backend that answers ahead (prefetch), the LLM's time is the prefetch plus the reads."""
    import time

    from globe.reasoning.backends.base import Choice, LLMBackend
    from globe.reasoning.gate import LLMOnlyChooser

    class SlowAhead(LLMBackend):
        name = "slow"

        def __init__(self):
            self.asked = 0

        @property
        def prefetches(self):
            return True

        def prefetch(self, questions):
            time.sleep(0.2)

        def choose(self, context, candidates):
            self.asked += 1
            return Choice(candidates[0], {c: 0.0 for c in candidates})

    am = ActivityModel().fit([d.activities for d in TRAIN])
    om = ObjectModel().fit([(r.activity, r.objects) for d in TRAIN for r in activity_runs(d, OBJECTS)])
    ev = evaluate_days(HOME, HOME.test, am, LLMOnlyChooser(om, SlowAhead()))
    assert ev.prefetch_s >= 0.2
    assert sum(r.latency_s for r in ev.objects) < 0.2  # what the records alone would have said
    from globe.evaluation.experiments import MethodRun

    assert MethodRun("llm_only", HOME.name, ev, ev, 0.0).llm_s >= 0.2  # timing.csv's llm_s
