"""The main job's stages: timed, logged one line each, kept in stages.csv; results per stage."""

import csv
import logging
from dataclasses import replace

import pytest

from globe.config import GlobeConfig
from globe.errors import ConfigError
from globe.evaluation import main_job


@pytest.fixture(scope="module")
def small(households):
    return [replace(households[n], train=households[n].train[:12], test=households[n].test[:2]) for n in ("A", "C")]


def test_reproduce_logs_and_records_every_stage(small, tmp_path, caplog):
    cfg = GlobeConfig().with_overrides({"evaluation.methods": ("persistence", "ngram"), "llm.backend": "none"})
    with caplog.at_level(logging.INFO, logger="globe.stages"):
        res = main_job.reproduce(cfg, small, tmp_path, with_robustness=False, with_anticipation=False)
    names = [s["stage"] for s in res.stages]
    assert names == ["load LLM", "table1: persistence", "table1: time_of_day", "table1: hour_activity",
                     "table1: ngram", "activity anticipation",
                     "table1: write results"]
    done = [r.getMessage() for r in caplog.records if "done in" in r.getMessage()]
    assert len(done) == len(names) and all(m.startswith(n) for m, n in zip(done, names))
    rows = list(csv.DictReader((tmp_path / "stages.csv").open()))
    assert [r["stage"] for r in rows] == names + ["total"]
    assert float(rows[-1]["seconds"]) == pytest.approx(sum(float(r["seconds"]) for r in rows[:-1]), abs=0.05)
    assert (tmp_path / "table1.csv").is_file() and res.table1.rows
    homes = {r["household"] for r in csv.DictReader((tmp_path / "activity_anticipation.csv").open())}
    assert homes == {h.name for h in small}


def test_unknown_or_missing_methods_are_config_errors():
    with pytest.raises(ConfigError, match="unknown method 'ngramm'"):
        main_job.check_methods(["ngram", "ngramm"])
    with pytest.raises(ConfigError, match="no method"):
        main_job.check_methods([])
