"""A Table I results folder holds every file, and what ran is read back from the objects."""

import csv
import json
from dataclasses import replace

from globe.config import GlobeConfig
from globe.evaluation.experiments import run_methods
from globe.evaluation.published import DataScope
from globe.evaluation.results import write_table1_results


def test_results_folder_traces_every_number(households, tmp_path):
    h = replace(households["B"], train=households["B"].train[:15], test=households["B"].test[:2])
    cfg = GlobeConfig().with_overrides({"models.object_marginal": True})
    runs = run_methods(cfg, [h], ["persistence", "ngram"], None)
    res = write_table1_results(tmp_path, runs, cfg, DataScope.of([h]))
    for name in ("table1.csv", "table1.md", "details.csv", "timing.csv", "selection.csv", "calibration.csv",
                 "config.json", "built.json", "table1.png", "reliability_activity.png", "reliability_object.png"):
        assert (tmp_path / name).is_file(), name
    built = json.loads((tmp_path / "built.json").read_text())
    assert built["ngram"]["B"]["activity"]["kind"] == "ActivityModel"
    assert built["ngram"]["B"]["chooser"] == {"kind": "ngram", "marginal": True}
    assert built["persistence"]["B"]["activity"]["kind"] == "PersistenceModel"
    records = list(csv.DictReader((tmp_path / "records" / "ngram_B_objects.csv").open()))
    ngram = next(r for r in runs if r.method == "ngram")
    assert len(records) == len(ngram.evaluation.objects)
    assert [r["predicted"] for r in records] == [o.predicted for o in ngram.evaluation.objects]
    details = {r["method"]: r for r in csv.DictReader((tmp_path / "details.csv").open())}
    assert float(details["ngram"]["activity_log_loss"]) > 0
    assert {r["method"] for r in res.rows} == {"persistence", "ngram"}
    table1 = (tmp_path / "table1.md").read_text()
    assert "household B test days" in table1 and "HOMER+" not in table1 and "published" not in table1
    assert json.loads((tmp_path / "data.json").read_text()) == {"title": "household B", "households": ["B"],
                                                               "homer_plus": False}


def test_published_figures_stand_beside_homer_plus_only(households):
    """HOMER+ is recognised by the content of its days, not by names or folders."""
    homer = DataScope.of(list(households.values()))
    assert homer.homer_plus and homer.title == "HOMER+" and homer.households == ("A", "B", "C")
    a = households["A"]
    assert DataScope.of([a]).homer_plus
    assert not DataScope.of([replace(a, test=a.test[:-1])]).homer_plus
    assert not DataScope.of([replace(a, name="my-home", train=a.train[1:])]).homer_plus
    assert DataScope.of([replace(a, name="my-home", train=a.train[1:])]).title == "household my-home"
