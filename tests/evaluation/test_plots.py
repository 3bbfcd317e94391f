"""The results plots stay readable: table1.png's legend clear of the bars and their values, the
paper's marks crossing no value and drawn beside a mean over HOMER+'s three households only;
activity_anticipation.png tells equal lines apart and labels its log axis in plain numbers."""

import re

import matplotlib.pyplot as plt
import pytest
from matplotlib.collections import LineCollection

from globe.config import GlobeConfig
from globe.evaluation.activity_anticipation import score_anticipation, write_activity_anticipation
from globe.evaluation.experiments import run_methods
from globe.evaluation.methods import METHODS
from globe.evaluation.plots import PUBLISHED_GID, VALUE_GID, table1_figure
from globe.evaluation.plots_anticipation import activity_horizon_figure
from globe.evaluation.published import TABLE1, DataScope
from globe.evaluation.results import write_table1_results
from globe.models.baselines import PersistenceModel
from tests.simulated import clock_home

HOMER_PLUS = DataScope("HOMER+", ("A", "B", "C"), True)
LABELS = {name: m.label for name, m in METHODS.items()}


def _rows(values: dict[str, tuple[float, float, float]]) -> list[dict]:
    """table1.csv rows (weighted, the mean only) with the given (activity, object, mean) F1."""
    return [{"method": m, "household": "mean", "average": "weighted", "activity_f1": a, "object_f1": o, "mean_f1": f}
            for m, (a, o, f) in values.items()]


def _drawn(fig):
    fig.canvas.draw()
    ax = fig.axes[0]
    values = [t for t in ax.texts if t.get_gid() == VALUE_GID]
    marks = [c for c in ax.collections if c.get_gid() == PUBLISHED_GID]
    return ax, values, marks


def _legend_texts(fig) -> list[str]:
    return [t.get_text() for legend in [*fig.legends, *filter(None, [a.get_legend() for a in fig.axes])]
            for t in legend.get_texts()]


def test_table1_legend_and_published_marks_leave_every_bar_and_value_readable():
    """The worst case: every bar exactly at its published value (the mark on the bar's top, where
    its value stands) and the best bar near the top right, where a legend inside the axes sat."""
    values = {m: TABLE1[m] for m in ("globe", "ngram", "slate_pro", "llm_only")}
    values["routine"] = (0.95, 0.93, 0.94)
    fig = table1_figure(_rows(values), LABELS, HOMER_PLUS)
    ax, labels, marks = _drawn(fig)
    assert len(labels) == 3 * len(values)
    [legend] = fig.legends
    box = legend.get_window_extent()
    assert not box.overlaps(ax.get_window_extent())  # outside the plotting area
    for artist in [*labels, *ax.patches]:
        assert not box.overlaps(artist.get_window_extent()), artist
    [mark] = marks
    assert isinstance(mark, LineCollection) and len(mark.get_segments()) == 3 * 4
    assert any("published" in t for t in _legend_texts(fig))
    for (x0, y), (x1, _) in mark.get_segments():
        (px0, py), (px1, _) = ax.transData.transform([(x0, y), (x1, y)])
        for label in labels:
            b = label.get_window_extent()
            crosses = px0 < b.x1 and b.x0 < px1 and b.y0 - 1 <= py <= b.y1 + 1
            assert not crosses, (label.get_text(), y)
    plt.close(fig)


@pytest.mark.parametrize("scope", [DataScope("HOMER+", ("A",), True), DataScope("household Mine", ("Mine",), False),
                                   DataScope("households X, Y, Z", ("X", "Y", "Z"), False)])
def test_table1_marks_the_paper_beside_homer_plus_three_households_only(scope):
    """The paper's figures are means over HOMER+'s three households: never beside one home, nor
    beside homes that are not HOMER+."""
    fig = table1_figure(_rows({m: TABLE1[m] for m in TABLE1}), LABELS, scope)
    ax, labels, marks = _drawn(fig)
    assert labels and not marks
    assert not any("published" in t for t in _legend_texts(fig))
    plt.close(fig)


def test_a_simulated_home_gets_its_own_names_and_no_published_marks(tmp_path):
    home = clock_home(20, 3)
    cfg = GlobeConfig()
    runs = run_methods(cfg, [home], ["persistence", "ngram"], None)
    res = write_table1_results(tmp_path, runs, cfg, DataScope.of([home]))
    assert not res.scope.homer_plus and (tmp_path / "table1.png").is_file()
    fig = table1_figure(res.rows, res.labels, res.scope)
    ax, labels, marks = _drawn(fig)
    assert len(labels) == 3 * 2 and not marks
    assert ax.get_ylabel() == "weighted F1 (household Clock)"
    plt.close(fig)


def _plain(text: str) -> bool:
    return re.fullmatch(r"\d+(\.\d+)?", text.replace("\N{MINUS SIGN}", "-")) is not None


def test_activity_anticipation_tells_equal_lines_apart_and_labels_in_plain_numbers(tmp_path):
    """With every weight of the time of day 0 the mix is the model itself: its line is said to be
    the same, drawn beneath the model's in another style, and the log axis reads 0.5, 1, 2..."""
    home = clock_home(20, 3)
    model = PersistenceModel().fit([d.activities for d in home.train])
    scores = score_anticipation(home.name, model, home.train, home.test, 6, 10, "chosen (persistence)", (0.0,) * 6)
    paths = write_activity_anticipation(tmp_path, [scores], "household Clock test days: the activity ahead")
    assert paths[2].is_file()
    fig = activity_horizon_figure(scores.rows(), "household Clock test days: the activity ahead")
    fig.canvas.draw()
    texts = _legend_texts(fig)
    assert "chosen (persistence) + time of day (same as chosen (persistence))" in texts
    assert "chosen (persistence)" in texts and "time_of_day" in texts and "hour + activity" in texts and len(texts) == 5
    top, bottom = fig.axes[0], fig.axes[1]
    lines = {line.get_label(): line for line in top.get_lines()}
    chosen = lines["chosen (persistence)"]
    mixed = lines["chosen (persistence) + time of day (same as chosen (persistence))"]
    assert chosen.get_zorder() > mixed.get_zorder()
    assert (chosen.get_linestyle(), chosen.get_marker()) != (mixed.get_linestyle(), mixed.get_marker())
    assert mixed.get_linewidth() > chosen.get_linewidth()  # the one beneath shows around the one on top
    styles = {(line.get_linestyle(), line.get_marker()) for line in top.get_lines()}
    assert len(styles) == 5
    assert bottom.get_yscale() == "log"
    for axis in (bottom.yaxis, bottom.xaxis, top.xaxis):
        shown = [t.get_text() for t in axis.get_ticklabels() if t.get_visible() and t.get_text()]
        assert len(shown) >= 2 and all(_plain(t) for t in shown), shown
        assert not any(t.get_text() for t in axis.get_ticklabels(minor=True)), "minor ticks carry no labels"
    assert [t.get_text() for t in top.xaxis.get_ticklabels()] == ["10", "20", "30", "40", "50", "60"]
    plt.close(fig)


def test_a_narrow_log_loss_range_still_gets_two_plain_ticks():
    """Log losses between two plain numbers (0.62 to 0.64): the axis widens to 0.5 and 1."""
    rows = [{"household": "H", "method": "model", "horizon_min": 10 * j, "accuracy": 0.5, "log_loss": 0.61 + 0.01 * j}
            for j in range(1, 4)]
    fig = activity_horizon_figure(rows, "narrow")
    fig.canvas.draw()
    shown = [t.get_text() for t in fig.axes[1].yaxis.get_ticklabels() if t.get_text()]
    assert shown == ["0.5", "1"]
    plt.close(fig)
