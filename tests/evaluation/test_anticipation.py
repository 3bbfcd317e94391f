"""The anticipation results folder: every file, the columns the issue asks for, one mean row per horizon."""

from __future__ import annotations

import csv

from globe.evaluation.anticipation import run_anticipation, write_anticipation_results
from globe.evaluation.lookahead import LOOKAHEAD_COLUMNS
from globe.evaluation.published import DataScope


def test_results_folder(households, config, tmp_path):
    cfg = config.with_overrides({"lookahead.methods": ("persistence",), "lookahead.last_reference": 12,
                                 "lookahead.cv_stride": 4, "policy.method": "persistence",
                                 "policy.curve_ratios": (1.0, 3.0)})
    messages: list[str] = []
    result = run_anticipation(cfg, {"A": households["A"]}, progress=messages.append)
    assert messages == ["lookahead and fetch policy: 3 households x methods (in parallel)"]  # baseline, oracle
    paths = write_anticipation_results(tmp_path, result, DataScope.of([households["A"]]))
    assert all(p.exists() and p.stat().st_size > 0 for p in paths)
    with (tmp_path / "lookahead.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert tuple(rows[0]) == LOOKAHEAD_COLUMNS
    assert [r["horizon_min"] for r in rows if r["household"] == "mean" and r["method"] == "persistence"] == \
        ["10", "20", "30", "40", "50", "60"]
    assert {r["household"] for r in rows} == {"A", "mean"}
    assert list(dict.fromkeys(r["method"] for r in rows)) == ["persistence", "hour_activity", "oracle"]
    with (tmp_path / "fetch_policy.csv").open() as fh:
        fetch = list(csv.DictReader(fh))
    for method in ("persistence", "hour_activity", "oracle"):  # the policy's fetches, the baseline's, the oracle's
        assert [r["configured"] for r in fetch if r["household"] == "A" and r["method"] == method] == ["False", "True"]
    with (tmp_path / "lookahead_selection.csv").open() as fh:
        chosen = [r for r in csv.DictReader(fh) if r["chosen"] == "True"]
    assert [r["horizon_min"] for r in chosen if r["method"] == "persistence"] == ["10", "20", "30", "40", "50", "60"]
    assert len({r["run_end"] for r in chosen if r["method"] == "persistence"}) == 1
    assert all(float(r["threshold"]) in cfg.lookahead.thresholds for r in chosen)
