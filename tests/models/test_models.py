"""Contract tests for both counting models (scikit-learn-style estimator checks)."""

import math

import pytest

from globe.errors import ConfigError, ModelFileError, NotFittedError
from globe.models.activity import ActivityModel
from globe.models.io import load_model, save_model
from globe.models.objects import ObjectModel
from globe.models.routine import RoutineModel

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


def test_run_start_token_conditions_the_first_object():
    m = ObjectModel(run_start_token=True).fit(RUNS)
    assert m.predict_proba("eat", ()) == {"bowl": pytest.approx(2 / 3), "plate": pytest.approx(1 / 3)}


MODELS = [
    pytest.param(lambda: ActivityModel(), DAYS, lambda m: m.predict_proba(["sleep", "wake"]), id="activity-longest"),
    pytest.param(lambda: ActivityModel(estimator="witten_bell", max_order=3, time_weight=1.0), DAYS,
                 lambda m: m.predict_proba(["sleep", "wake", "eat"]), id="activity-wb-time"),
    pytest.param(lambda: RoutineModel(order=2, time_weight=1.0), DAYS,
                 lambda m: m.predict_proba(["sleep", "wake", "eat"]), id="activity-routine"),
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
