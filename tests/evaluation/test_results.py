"""A Table I results folder holds every file, and what ran is read back from the objects."""

import csv
import json
from dataclasses import replace

from globe.config import GlobeConfig
from globe.evaluation.experiments import run_methods
from globe.evaluation.published import DEPARTURES, DataScope
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
                                                               "homer_plus": False, "uses": "every relocation",
                                                               "activities": "annotated"}


def test_published_figures_stand_beside_homer_plus_only(households):
    """HOMER+ is recognised by the content of its days, not by names or folders."""
    homer = DataScope.of(list(households.values()))
    assert homer.homer_plus and homer.title == "HOMER+" and homer.households == ("A", "B", "C")
    a = households["A"]
    assert DataScope.of([a]).homer_plus
    assert not DataScope.of([replace(a, test=a.test[:-1])]).homer_plus
    assert not DataScope.of([replace(a, name="my-home", train=a.train[1:])]).homer_plus
    assert DataScope.of([replace(a, name="my-home", train=a.train[1:])]).title == "household my-home"


def _headers(markdown: str) -> list[list[str]]:
    """The header cells of every Markdown table in ``markdown``."""
    lines = markdown.splitlines()
    return [[c.strip() for c in line.strip("|").split("|")] for line, below in zip(lines, lines[1:])
            if line.startswith("|") and below.startswith("|---")]


def test_a_home_of_ones_own_gets_plain_names_and_its_columns_once(tmp_path):
    """One home that is not HOMER+: no "Table I/II" (those are the paper's), and its scores once,
    not again as a "mean" of that one household."""
    from tests.simulated import clock_home

    home = clock_home(20, 3)
    cfg = GlobeConfig()
    write_table1_results(tmp_path, run_methods(cfg, [home], ["persistence", "ngram"], None), cfg, DataScope.of([home]))
    md = (tmp_path / "table1.md").read_text(encoding="utf-8")
    assert "Table I" not in md and "published" not in md and "mean act" not in md
    assert md.startswith("# Scores on the test days (household Clock)\n")
    assert "\n# Time for the whole test split\n" in md
    headers = _headers(md)
    assert headers[:3] == [["Method", "Clock act", "Clock obj", "Clock mean"]] * 3
    for cells in headers:
        assert len(cells) == len(set(cells)), cells
    assert json.loads((tmp_path / "data.json").read_text()) == {"title": "household Clock", "households": ["Clock"],
                                                               "homer_plus": False, "uses": DEPARTURES,
                                                               "activities": "annotated"}


def test_homer_plus_tables_keep_the_papers_layout():
    """On HOMER+ (one household or three) Table I keeps every household's columns, the mean's and
    the published rows beneath, under the mean, as before."""
    from pathlib import Path

    from globe.evaluation.methods import METHODS
    from globe.evaluation.report import table1_markdown

    reference = Path(__file__).resolve().parents[2] / "reference" / "homer_plus" / "table1.csv"
    rows = list(csv.DictReader(reference.open(encoding="utf-8")))
    labels = {name: m.label for name, m in METHODS.items()}
    md = table1_markdown(rows, labels, "weighted", DataScope("HOMER+", ("A", "B", "C"), True))
    assert md.startswith("F1 (weighted) on HOMER+ test days\n")
    assert _headers(md)[0] == ["Method", *[f"{h} {p}" for h in ("A", "B", "C", "mean") for p in ("act", "obj", "mean")]]
    assert md.rstrip().endswith("| *stot (published)* | " + " | ".join(["–"] * 11 + ["0.43"]) + " |")
    b = [r for r in rows if r["household"] == "B"]
    one = b + [dict(r, household="mean") for r in b]
    md = table1_markdown(one, labels, "weighted", DataScope("HOMER+", ("B",), True))
    assert _headers(md)[0] == ["Method", "B act", "B obj", "B mean", "mean act", "mean obj", "mean mean"]
    assert "| *globe (published)* | – | – | – | 0.80 | 0.65 | 0.73 |" in md
