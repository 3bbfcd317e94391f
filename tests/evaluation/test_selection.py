"""Cross-validation's one home: folds, the rule that chooses, and a memo keyed by what results depend on."""

from dataclasses import replace

import pytest

from globe.evaluation.selection import DataKey, FitKey, Fold, Memo, SearchKey, best_of, fingerprint, folds, grid, select


def test_folds_are_contiguous_and_cover_every_item_once():
    splits = folds(13, 5)
    assert [v for _, v in splits] == [[0, 1, 2], [3, 4], [5, 6, 7], [8, 9], [10, 11, 12]]  # bounds round(i * 13 / 5)
    for train, val in splits:
        assert sorted(train + val) == list(range(13))
    assert len(folds(3, 10)) == 3 and len(folds(5, 1)) == 2  # at most one fold per item, at least two


def test_grid_varies_the_last_key_fastest():
    assert grid({"a": [1, 2], "b": ["x", "y"]}) == [{"a": 1, "b": "x"}, {"a": 1, "b": "y"}, {"a": 2, "b": "x"},
                                                     {"a": 2, "b": "y"}]


def test_the_best_candidate_wins_and_near_ties_go_to_the_first_listed():
    assert best_of([("simple", 0.5), ("complex", 0.7), ("other", 0.6)]) == "complex"
    tie = 0.1 + 0.2  # 0.30000000000000004: a last bit must not beat the simpler candidate
    assert best_of([("simple", 0.3), ("complex", tie)]) == "simple"
    assert best_of([("simple", 0.3), ("complex", 0.3 + 1e-6)]) == "complex"
    with pytest.raises(ValueError):
        best_of([])
    chosen = select(grid({"x": [1, 2, 3]}), lambda c: -abs(c["x"] - 2))
    assert chosen.best == {"x": 2} and [s for _, s in chosen.scores] == [-1, 0, -1] and chosen.seconds >= 0


def test_data_keys_follow_the_content_of_the_days(households):
    h = households["A"]
    key = DataKey.of(h)
    assert key == DataKey.of(replace(h, test=()))  # the same training days, another object
    assert key != DataKey.of(replace(h, train=h.train[:-1]))
    changed = replace(h.train[3], activities=("idle",) + h.train[3].activities[1:])
    assert key != DataKey.of(replace(h, train=h.train[:3] + (changed,) + h.train[4:]))  # one label differs
    assert fingerprint(h.train) == fingerprint(list(h.train))
    assert DataKey.of(h).days != DataKey.of(h, h.test).days


def test_memo_keeps_a_result_under_every_input_it_names(households):
    h = households["A"]
    memo, calls = Memo(), []
    fold = Fold(DataKey.of(h), 5, 0)

    def fit(label):
        calls.append(label)
        return label

    assert memo.get(FitKey("m", fold.data, fold, ("p", 1), "previous"), fit, "a") == "a"
    assert memo.get(FitKey("m", fold.data, fold, ("p", 1), "previous"), fit, "b") == "a"  # kept
    assert memo.get(FitKey("m", fold.data, fold, ("p", 1), "current"), fit, "c") == "c"  # another alignment
    assert memo.get(FitKey("m", fold.data, Fold(fold.data, 5, 1), ("p", 1), "previous"), fit, "d") == "d"
    assert memo.get(SearchKey("m", fold.data, ("p", 1), None, 5, "previous"), fit, "e") == "e"  # another kind of key
    assert calls == ["a", "c", "d", "e"] and len(memo) == 4
    searches = set(memo.entries(lambda k: isinstance(k, SearchKey)))
    assert searches == {SearchKey("m", fold.data, ("p", 1), None, 5, "previous")}


def test_a_choice_at_the_edge_of_its_grid_widens_the_grid_until_it_is_inside():
    """The measure peaks at 100; the grid (10, 20) stops before it: 40, 80 and 160 are tried in
    turn, 80 wins inside the widened grid, and no setting is left at an edge. With one round the
    choice still sits at the edge and says so. Each candidate is measured once."""
    from globe.evaluation.selection import select_widening

    measured = []

    def measure(c):
        measured.append(c["slot"])
        return {"f1": -abs(c["slot"] - 100)}

    def twice(edge, upward):
        return edge * 2 if upward else (edge // 2 if edge >= 20 else None)

    chosen = select_widening([{"slot": 10}, {"slot": 20}], measure, "f1", {"slot": twice})
    assert chosen.best == {"slot": 80} and chosen.at_edge == ()
    assert sorted(measured) == [10, 20, 40, 80, 160]
    short = select_widening([{"slot": 10}, {"slot": 20}], measure, "f1", {"slot": twice}, rounds=1)
    assert short.best == {"slot": 40} and short.at_edge == ("slot",)
    other = select_widening([{"kind": "a"}, {"kind": "b", "slot": 10}], lambda c: {"f1": c["kind"] == "a"}, "f1",
                            {"slot": twice})
    assert other.best == {"kind": "a"} and other.at_edge == ()  # a winner without the setting is not widened
