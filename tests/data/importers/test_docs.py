"""docs/your-home.md is run as written: its titled blocks are the files, its bash blocks the
commands, and what its prose claims about the result is checked here."""

import re
import shlex
import subprocess
import sys
from pathlib import Path

import pytest

from globe.data.csv_logs import load_household

DOC = Path(__file__).resolve().parents[3] / "docs" / "your-home.md"
_BLOCK = re.compile(r"^```(\w+)([^\n]*)\n(.*?)^```$", re.M | re.S)


def _blocks():
    files, commands = {}, []
    for lang, info, body in _BLOCK.findall(DOC.read_text(encoding="utf-8")):
        title = re.search(r'title="([^"]+)"', info)
        if title:
            files[title.group(1)] = body
        elif lang == "bash":
            commands += [line for line in body.replace("\\\n", " ").splitlines() if line.strip()]
    return files, commands


def _globe(line, cwd):
    args = shlex.split(line)
    assert args[0] == "globe", line
    return subprocess.run([sys.executable, "-m", "globe", *args[1:]], cwd=cwd, capture_output=True, text=True,
                          timeout=300)


@pytest.fixture(scope="module")
def ran(tmp_path_factory):
    folder = tmp_path_factory.mktemp("your-home")
    files, commands = _blocks()
    for name, body in files.items():
        (folder / name).write_text(body, encoding="utf-8")
    return folder, {line: _globe(line, folder) for line in commands}


def test_every_command_of_the_page_succeeds(ran):
    _, results = ran
    assert len(results) == 7
    for line, res in results.items():
        assert res.returncode == 0, (line, res.stderr)


def test_the_page_says_what_the_imports_wrote(ran):
    folder, _ = ran
    casas = load_household(folder, "MyCasasHome")
    assert casas.objects == ("i006",)
    assert [d.name for d in casas.train + casas.test] == ["train/2010-11-04", "test/2010-11-05"]
    day = casas.train[0]
    assert day.activities[:7] == ("Sleeping",) * 6 + ("idle",) and day.locations[6] == ("in_use#2",)
    assert day.activities[7] == "Meal_Preparation"
    kitchen = load_household(folder, "MyCasasKitchen")
    assert kitchen.objects == ("medicine_box", "cabinet") and kitchen.train[0].minutes[1] == 365
    assert load_household(folder, "MyOrdonezHome").objects == ("cupboard", "fridge", "toaster")
    assert load_household(folder, "MyKasterenHome").objects == ("cups_cupboard", "fridge")
    ha = load_household(folder, "MyHaHome")
    assert ha.objects == ("fridge", "kettle")
    breakfast = [m for m, a in zip(ha.train[0].minutes, ha.train[0].activities) if a == "breakfast"]
    assert breakfast[0] == 410  # 05:48:10 UTC is 06:48:10 in Amsterdam: the 06:50 row is the first


def test_the_error_the_page_shows_is_the_one_globe_prints(tmp_path):
    files, _ = _blocks()
    lines = files["casas.txt"].splitlines()
    lines[12] = lines[12].replace("07:11:30", "07:00:00")
    (tmp_path / "casas.txt").write_text("\n".join(lines) + "\n", encoding="utf-8")
    res = _globe("globe data import casas casas.txt Broken", tmp_path)
    shown = re.search(r"`(casas\.txt:13: .*?)`", " ".join(DOC.read_text(encoding="utf-8").split()), re.S)
    assert res.returncode == 1 and shown is not None
    assert res.stderr.strip() == f"error: {shown.group(1)}"
