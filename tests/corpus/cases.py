"""The malformed-input corpus: what a user, a file or a script sends, and what GLOBE must answer.

Each case builds its input under a fresh folder (a copy of the tiny valid home of
:mod:`tests.corpus.homes`, then one mutation), runs ``globe`` with the arguments it returns, and
states the exact outcome: the exit status and the one stderr line (``{root}`` is the data
folder, ``{home}`` the household folder), or a check of the result.
"""

from __future__ import annotations

import json
import shutil
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from tests.corpus.homes import NODES, activity_only, day_rows, day_text, nodes_text, write_home

VALIDATE = ["data", "validate", "--households", "T"]
DAY_HEADER = ("minute", "activity", "cup", "plate")


@dataclass(frozen=True)
class Case:
    name: str
    build: Callable[[Path, Path], list[str]]  # (data root, household folder) -> argv
    code: int
    stderr: str | None = None  # the exact single line, with {root}/{home}; None: stderr must be empty
    check: Callable[[Path, Path, str], None] | None = None  # (root, home, stdout) -> asserts
    match: str | None = None  # a regular expression the line must match in full, where a detail varies


def _edit_day(rel: str, edit: Callable[[list[list[str]]], list[list[str]]], header: tuple[str, ...] | None = None):
    def build(root: Path, home: Path) -> list[str]:
        rows = edit(day_rows())
        text = day_text(rows) if header is None else day_text(rows, header)
        (home / rel).write_text(text, encoding="utf-8")
        return [*VALIDATE, "--data", str(root)]
    return build


def _set(row: int, col: int, value: str):
    def edit(rows: list[list[str]]) -> list[list[str]]:
        rows[row][col] = value
        return rows
    return edit


def _write(rel: str, data: bytes | str, argv: list[str] | None = None):
    def build(root: Path, home: Path) -> list[str]:
        path = home / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        if isinstance(data, bytes):
            path.write_bytes(data)
        else:
            path.write_text(data, encoding="utf-8")
        return [*(argv or VALIDATE), "--data", str(root)]
    return build


def _nodes(edit: Callable[[list[tuple]], list[tuple]]):
    return _write("nodes.csv", nodes_text(edit(list(NODES))))


def _replace_node(label: str, **changes):
    keys = ("node", "class", "category", "movable", "start_location")

    def edit(nodes: list[tuple]) -> list[tuple]:
        return [tuple(changes.get(k, v) for k, v in zip(keys, n)) if n[0] == label else n for n in nodes]
    return edit


def _valid_home_check(train: int, test: int) -> Callable[[Path, Path, str], None]:
    def check(root: Path, home: Path, stdout: str) -> None:
        from globe.data.csv_logs import load_household

        h = load_household(root, home.name)
        assert (len(h.train), len(h.test)) == (train, test)
        assert "all files valid" in stdout
    return check


def _rename(src: str, dst: str):
    def build(root: Path, home: Path) -> list[str]:
        (home / src).rename(home / dst)
        return [*VALIDATE, "--data", str(root)]
    return build


def _long_day(root: Path, home: Path) -> list[str]:
    rows = [[str(360 + 10 * t), "idle", "counter#3", "counter#3"] for t in range(400)]
    (home / "train" / "000.csv").write_text(day_text(rows), encoding="utf-8")
    return [*VALIDATE, "--data", str(root)]


def _gap(root: Path, home: Path) -> list[str]:
    rows = day_rows()
    del rows[4]  # 400 is missing: 390 -> 410
    (home / "train" / "002.csv").write_text(day_text(rows), encoding="utf-8")
    return [*VALIDATE, "--data", str(root)]


def _gap_resampled(root: Path, home: Path) -> list[str]:
    _gap(root, home)
    cfg = root / "globe.toml"
    cfg.write_text('[data]\nresample = "locf"\n', encoding="utf-8")
    return [*VALIDATE, "--config", str(cfg), "--data", str(root)]


def _check_resampled(root: Path, home: Path, stdout: str) -> None:
    from globe.data.csv_logs import load_household

    day = load_household(root, "T", resample="locf").train[2]
    assert day.minutes == tuple(range(360, 470, 10))
    assert day.activities[4] == day.activities[3] == day_rows()[3][1]  # 400 carries 390 forward


def _both_folders(root: Path, home: Path) -> list[str]:
    shutil.copytree(home, root / "T")
    return [*VALIDATE, "--data", str(root)]


def _exact_name(root: Path, home: Path) -> list[str]:
    write_home(root, "Y")  # asked for Y: the folder Y, never HouseholdY
    (root / "HouseholdYY").mkdir()
    return ["data", "validate", "--households", "Y", "--data", str(root)]


def _no_test(root: Path, home: Path) -> list[str]:
    shutil.rmtree(home / "test")
    return ["evaluate", "--households", "T", "--methods", "ngram", "--backend", "none",
            "--out", str(root / "results"), "--data", str(root)]


def _check_no_results(root: Path, home: Path, stdout: str) -> None:
    assert not (root / "results").exists()


def _activity_only(root: Path, home: Path) -> list[str]:
    activity_only(root, "HouseholdQ")
    return ["train", "--household", "Q", "--model-dir", str(root / "m"), "--data", str(root)]


def _check_activity_only(root: Path, home: Path, stdout: str) -> None:
    from globe.models.io import load_household_model

    model = load_household_model(root / "m")
    assert model.objects_columns == ()
    assert model.activity.predict_proba(("sleeping",)) == {"breakfast": 1.0}
    assert model.objects.predict_proba("breakfast") == {}


def _trained(root: Path, home: Path) -> Path:
    from globe.cli.main import main

    try:
        main(["train", "--household", "T", "--model-dir", str(root / "m"), "--data", str(root)])
    except SystemExit as done:
        assert done.code == 0
    return root / "m"


def _predict(*extra: str, edit: Callable[[Path], None] | None = None):
    def build(root: Path, home: Path) -> list[str]:
        model_dir = _trained(root, home)
        if edit is not None:
            edit(model_dir)
        return ["predict", "--model-dir", str(model_dir), *extra, "--data", str(root)]
    return build


def _legacy(model_dir: Path) -> None:
    (model_dir / "model.json").unlink()
    (model_dir / "activity.json").write_text("{}")
    (model_dir / "objects.json").write_text("{}")


def _truncate(model_dir: Path) -> None:
    data = (model_dir / "model.json").read_bytes()
    (model_dir / "model.json").write_bytes(data[: len(data) // 2])


def _mix(model_dir: Path) -> None:
    """The activity model of this save with the object model of another (trained on fewer days)."""
    payload = json.loads((model_dir / "model.json").read_text())
    payload["objects"]["data"] = payload["objects"]["data"][:3]
    (model_dir / "model.json").write_text(json.dumps(payload))


def _other_household(root: Path, home: Path) -> list[str]:
    model_dir = _trained(root, home)
    write_home(root, "HouseholdU")
    return ["predict", "--model-dir", str(model_dir), "--household", "U", "--history", "sleeping", "--data", str(root)]


def _other_map(root: Path, home: Path) -> list[str]:
    model_dir = _trained(root, home)
    shutil.rmtree(home)
    write_home(root, "HouseholdT", nodes=nodes_text(NODES + [("shelf#7", "shelf", "Furniture", 0, "kitchen#2")]))
    return ["predict", "--model-dir", str(model_dir), "--household", "T", "--history", "sleeping", "--data", str(root)]


def _model_dir_is_file(root: Path, home: Path) -> list[str]:
    (root / "m").write_text("a file")
    return ["train", "--household", "T", "--model-dir", str(root / "m" / "sub"), "--data", str(root)]


def _levels(root: Path, home: Path) -> list[str]:
    return ["noise", "--households", "T", "--levels", "7", "--backend", "none",
            "--noise-dir", str(root / "noise"), "--data", str(root)]


def _check_no_noise(root: Path, home: Path, stdout: str) -> None:
    assert not (root / "noise").exists()


def _markup_folder(root: Path, home: Path) -> list[str]:
    return ["data", "validate", "--data", str(root / "root:x:0 [red]x[/red]")]


def _no_test_train(root: Path, home: Path) -> list[str]:
    shutil.rmtree(home / "test")
    return ["train", "--household", "T", "--model-dir", str(root / "m"), "--data", str(root)]


def _check_model_saved(root: Path, home: Path, stdout: str) -> None:
    assert (root / "m" / "model.json").is_file(), "no model"


def _bad_minute(line: int, cell: str) -> str:
    """The one message for a minute cell that is not a whole number of minutes of the day."""
    return (f"error: {{home}}/train/000.csv:{line}: column 'minute': '{cell}' "
            "is not a whole number of minutes in 0..1440 (ASCII digits only)")


def _off_step(path: str, line: int, minute: int, gap: int, previous: int) -> str:
    """The message for a minute that is not one step after the previous row."""
    return (f"error: {{home}}/{path}:{line}: column 'minute': {minute} is {gap} minutes after {previous}; "
            "this household's step is 10 minutes "
            "(fix the log, or set data.resample = \"locf\" to resample to the step)")


CASES: list[Case] = [
    # -- usage: one line, exit 2 ---------------------------------------------------------------------
    Case("missing option", lambda r, h: ["train", "--model-dir", str(r / "m")], 2,
         "usage error: Missing option '--household'. (see 'globe train --help')"),
    Case("unknown option", lambda r, h: ["train", "--household", "T", "--model-dir", str(r / "m"), "--bogus"], 2,
         "usage error: No such option: --bogus (see 'globe train --help')"),
    Case("bad integer", lambda r, h: ["predict", "--model-dir", str(r / "m"), "--top", "three"], 2,
         "usage error: Invalid value for '--top': Input should be a valid integer, "
         "unable to parse string as an integer (see 'globe predict --help')"),
    Case("predict --top 0", lambda r, h: ["predict", "--model-dir", str(r / "m"), "--top", "0"], 2,
         "usage error: Invalid value for '--top': Input should be greater than or equal to 1 "
         "(see 'globe predict --help')"),
    Case("unknown command", lambda r, h: ["fly"], 2, "usage error: No such command 'fly'. (see 'globe --help')"),
    Case("noise level 7 is not a fraction", _levels, 1,
         "error: invalid configuration: noise.levels.0: Input should be less than or equal to 1 (got '7')",
         _check_no_noise),
    # -- text and encodings --------------------------------------------------------------------------
    Case("BOM in a day file (Excel CSV UTF-8)", _write("train/000.csv", "\ufeff" + day_text()), 0, None,
         _valid_home_check(3, 1)),
    Case("BOM in nodes.csv", _write("nodes.csv", "\ufeff" + nodes_text()), 0, None, _valid_home_check(3, 1)),
    Case("CRLF line ends and quoted cells", _write("train/000.csv", day_text().replace(",sleeping,", ',"sleeping",')
                                                   .replace("\n", "\r\n")), 0, None, _valid_home_check(3, 1)),
    Case("Latin-1 byte in a day file",
         _write("train/000.csv", day_text().replace("reading", "r\xe9ading").encode("latin-1")), 1,
         "error: {home}/train/000.csv:8: not UTF-8 text (byte 213: invalid continuation byte); save the file as UTF-8"),
    Case("UTF-16 day file", _write("train/000.csv", day_text().encode("utf-16")), 1,
         "error: {home}/train/000.csv:1: not UTF-8 text (byte 0: invalid start byte); save the file as UTF-8"),
    Case("cell over 128 KiB", _edit_day("train/000.csv", _set(0, 1, "a" * (129 << 10))), 1,
         "error: {home}/train/000.csv:2: not valid CSV: field larger than field limit (131072)"),
    Case("control character in an activity", _edit_day("train/000.csv", _set(2, 1, "break\x07fast")), 1,
         "error: {home}/train/000.csv:4: column 'activity': activity 'break\\x07fast' contains a control character"),
    Case("empty day file", _write("train/001.csv", ""), 1,
         "error: {home}/train/001.csv:1: empty file (expected a header line)"),
    Case("header only", _write("train/001.csv", "minute,activity,cup,plate\n"), 1,
         "error: {home}/train/001.csv:2: no observation rows after the header"),
    Case("ragged row", _edit_day("train/000.csv", lambda rows: rows[:3] + [rows[3][:3]] + rows[4:]), 1,
         "error: {home}/train/000.csv:5: column 'plate': ragged row: 3 fields, header has 4"),
    Case("duplicate column",
         _edit_day("train/000.csv", lambda rows: [r + [r[2]] for r in rows], (*DAY_HEADER, "cup")), 1,
         "error: {home}/train/000.csv:1: column 'cup': duplicate column"),
    Case("extra column",
         _edit_day("train/000.csv", lambda rows: [r + ["x"] for r in rows], (*DAY_HEADER, "note")), 1,
         "error: {home}/train/000.csv:1: column 'note': not a movable node of this home (see nodes.csv)"),
    Case("empty activity", _edit_day("train/000.csv", _set(5, 1, " ")), 1,
         "error: {home}/train/000.csv:7: column 'activity': empty activity"),
    Case("unknown location", _edit_day("train/000.csv", _set(5, 3, "garage#9")), 1,
         "error: {home}/train/000.csv:7: column 'plate': unknown location 'garage#9' (not in nodes.csv)"),
    Case("object inside itself in a day", _edit_day("train/000.csv", _set(5, 2, "cup#5")), 1,
         "error: {home}/train/000.csv:7: column 'cup': 'cup#5' is inside itself"),
    Case("objects inside each other in a day",
         _edit_day("train/000.csv", lambda rows: _set(5, 3, "cup#5")(_set(5, 2, "plate#6")(rows))), 1,
         "error: {home}/train/000.csv:7: column 'cup': containment cycle: 'cup#5' is in 'plate#6' is in 'cup#5'"),
    # -- minutes -------------------------------------------------------------------------------------
    Case("negative minute", _edit_day("train/000.csv", _set(0, 0, "-10")), 1, _bad_minute(2, "-10")),
    Case("minute 99999", _edit_day("train/000.csv", _set(10, 0, "99999")), 1, _bad_minute(12, "99999")),
    Case("400-row day past midnight", _long_day, 1, _bad_minute(111, "1450")),
    Case("3_90 is not 390", _edit_day("train/000.csv", _set(3, 0, "3_90")), 1, _bad_minute(5, "3_90")),
    Case("non-ASCII digits", _edit_day("train/000.csv", _set(3, 0, "\uff13\uff19\uff10")), 1, _bad_minute(5, "３９０")),
    Case("decimal minute", _edit_day("train/000.csv", _set(3, 0, "390.0")), 1, _bad_minute(5, "390.0")),
    Case("minutes going back", _edit_day("train/000.csv", _set(3, 0, "370")), 1,
         "error: {home}/train/000.csv:5: column 'minute': 370 is not after 380 (minutes must increase)"),
    Case("a gap in the log", _gap, 1, _off_step("train/002.csv", 6, 410, 20, 390)),
    Case("a clock jump off the grid", _edit_day("test/000.csv", _set(3, 0, "395")), 1,
         _off_step("test/000.csv", 5, 395, 15, 380)),
    Case("a gap, resampled by request", _gap_resampled, 0, None, _check_resampled),
    # -- nodes.csv ----------------------------------------------------------------------------------
    Case("node inside itself", _nodes(_replace_node("cup#5", start_location="cup#5")), 1,
         "error: {home}/nodes.csv:6: column 'start_location': 'cup#5' is inside itself "
         "(only the home or a room may be the top of the map)"),
    Case("two nodes with one label", _nodes(lambda ns: ns + [("cup#5", "cup", "placable_objects", 0, "table#4")]), 1,
         "error: {home}/nodes.csv:8: column 'node': duplicate node 'cup#5' (first at line 6)"),
    Case("containment cycle", _nodes(lambda ns: _replace_node("table#4", start_location="counter#3")(
        _replace_node("counter#3", start_location="table#4")(ns))), 1,
         "error: {home}/nodes.csv:4: column 'start_location': containment cycle: "
         "counter#3 is in table#4 is in counter#3"),
    Case("chain without a room", _nodes(_replace_node("table#4", start_location="home#1")), 1,
         "error: {home}/nodes.csv:5: column 'start_location': 'table#4' is not in a room "
         "(its start_location chain reaches the top without a node of category Rooms)"),
    Case("label and class disagree", _nodes(_replace_node("plate#6", **{"class": "dish"})), 1,
         "error: {home}/nodes.csv:7: column 'node': label 'plate#6' does not start with its class 'dish' "
         "(labels are class#id)"),
    Case("movable is not 0 or 1", _nodes(_replace_node("plate#6", movable="yes")), 1,
         "error: {home}/nodes.csv:7: column 'movable': 'yes' is not 0 or 1"),
    Case("unknown start location", _nodes(_replace_node("plate#6", start_location="attic#9")), 1,
         "error: {home}/nodes.csv:7: column 'start_location': unknown location 'attic#9'"),
    # -- folders and file names ---------------------------------------------------------------------------
    Case("001.CSV is a day", _rename("train/001.csv", "train/001.CSV"), 0, None, _valid_home_check(3, 1)),
    Case("Nodes.CSV and Train/ match",
         lambda r, h: (_rename("nodes.csv", "Nodes.CSV")(r, h), _rename("train", "Train")(r, h))[1], 0, None,
         _valid_home_check(3, 1)),
    Case("001.csv and 001.CSV", _write("train/001.CSV", day_text()), 1,
         "error: {home}/train: 001.CSV and 001.csv are the same day (names differ only in case)"),
    Case("folder named x.csv", lambda r, h: ((h / "train" / "x.csv").mkdir(), [*VALIDATE, "--data", str(r)])[1], 1,
         "error: {home}/train/x.csv: is a folder, not a day file"),
    Case("stray file among days", _write("train/notes.txt", "hello"), 1,
         "error: {home}/train/notes.txt: not a day file (day files end in .csv; remove or rename it)"),
    Case("both T and HouseholdT", _both_folders, 1,
         "error: {root}: household 'T' is ambiguous: both T/ and HouseholdT/ exist; name the folder ('HouseholdT')"),
    Case("Y is the folder Y", _exact_name, 0, None,
         lambda r, h, out: None if "all files valid" in out else (_ for _ in ()).throw(AssertionError(out))),
    Case("household name with a path", lambda r, h: ["data", "validate", "--households", "../T", "--data", str(r)], 1,
         "error: {root}: household name '../T' is not a folder name (set the data folder with --data)"),
    Case("missing household", lambda r, h: ["data", "validate", "--households", "Z", "--data", str(r)], 1,
         "error: {root}: household 'Z' not found (no folder Z/ or HouseholdZ/); available: T"),
    Case("no training days", lambda r, h: (shutil.rmtree(h / "train"), [*VALIDATE, "--data", str(r)])[1], 1,
         "error: {home}: no training days (expected train/*.csv)"),
    Case("markup in a message stays literal", _markup_folder, 1,
         "error: {root}/root:x:0 [red]x[/red]: data folder not found (from --data); pass --data DIR or set GLOBE_DATA"),
    # -- valid inputs that used to fail -------------------------------------------------------------------
    Case("no test days: evaluate says there is nothing to score", _no_test, 1,
         "error: {home}: household T has no test days (test/*.csv): nothing to score; "
         "evaluate households with test days (it can still be trained and served)", _check_no_results),
    Case("no test days: train works", _no_test_train, 0, None, _check_model_saved),
    Case("activity-only home trains and predicts", _activity_only, 0, None, _check_activity_only),
    Case("a line of spaces and tabs is a blank line",
         _write("train/000.csv", day_text().replace("\n", "\n \t \n", 3)), 0, None, _valid_home_check(3, 1)),
    Case("minutes with many leading zeros", _edit_day("train/000.csv", _set(0, 0, "000000000360")), 0, None,
         _valid_home_check(3, 1)),
    # -- messages that name the right thing -----------------------------------------------------------------
    Case("a duplicated object column, not the column it pushed out",
         _edit_day("train/000.csv", lambda rows: rows, ("minute", "activity", "cup", "cup")), 1,
         "error: {home}/train/000.csv:1: column 'cup': duplicate column"),
    Case("NUL byte in the header",
         _edit_day("train/000.csv", lambda rows: rows, ("min\x00ute", "activity", "cup", "plate")), 1,
         "error: {home}/train/000.csv:1: header cell 1 ('min\\x00ute') contains a NUL byte: a binary file, or text "
         "saved as UTF-16? (save it as UTF-8)"),
    # -- model files ------------------------------------------------------------------------------------
    Case("predict without a model", lambda r, h: ["predict", "--model-dir", str(r / "none")], 1,
         "error: {root}/none: no such model folder (create one with: globe train --household NAME --model-dir DIR)"),
    Case("old separate model files", _predict(edit=_legacy), 1,
         "error: {root}/m/model.json: model file not found (activity.json and objects.json are from an older GLOBE "
         "that saved the models separately; retrain with globe train)"),
    Case("model file not UTF-8", _predict(edit=lambda m: (m / "model.json").write_bytes(b"\xff\xfe{}")), 1,
         "error: {root}/m/model.json: not a GLOBE model file (not UTF-8 text at byte 0)"),
    Case("model file of another JSON shape", _predict(edit=lambda m: (m / "model.json").write_text("[1, 2]")), 1,
         "error: {root}/m/model.json: not a GLOBE household model (format 'list')"),
    Case("model file cut in half (killed copy)", _predict(edit=_truncate), 1, None,
         match=r"error: .*/m/model\.json: not JSON \(line 1, column \d+: .*\); the file is damaged or truncated"),
    Case("mixed model parts", _predict(edit=_mix), 1,
         "error: {root}/m/model.json: checksum mismatch (the file was edited, mixed with another or damaged); "
         "retrain it"),
    Case("model of another household", _other_household, 1,
         "error: {root}/m/model.json: trained for household 'HouseholdT', not 'HouseholdU'"),
    Case("unknown --objects", _predict("--history", "breakfast", "--objects", "cup,spoon"), 1,
         "error: --objects: unknown object 'spoon'; known: cup, plate"),
    Case("unknown --history", _predict("--history", "flying"), 1,
         "error: --history: unknown activity 'flying'; known: breakfast, cleaning, idle, reading, sleeping"),
    Case("unwritable --model-dir", _model_dir_is_file, 1,
         "error: {root}/m/sub: cannot write the model: Not a directory"),
]

# A map change is caught by its fingerprint even under the same folder name.
CASES.append(Case("model for another map", _other_map, 1, None,
                  match=r"error: .*/m/model\.json: trained for another map "
                        r"\(household 'HouseholdT', map sha256:[0-9a-f]{12}\.\.\.; "
                        r"this map is sha256:[0-9a-f]{12}\.\.\.\); retrain it for this household"))
