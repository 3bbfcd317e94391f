"""Every case of the malformed-input corpus, run through the real ``globe`` entry point."""

from __future__ import annotations

import re

import pytest

from globe.cli.main import main
from tests.corpus.cases import CASES, Case
from tests.corpus.homes import write_home


def run_globe(argv: list[str], capsys) -> tuple[int, str, str]:
    with pytest.raises(SystemExit) as done:
        main(argv)
    captured = capsys.readouterr()
    return int(done.value.code or 0), captured.out, captured.err


@pytest.mark.parametrize("case", CASES, ids=[c.name for c in CASES])
def test_corpus_case(case: Case, tmp_path, capsys, monkeypatch):
    monkeypatch.delenv("GLOBE_DATA", raising=False)
    monkeypatch.chdir(tmp_path)
    root = tmp_path / "data"
    home = write_home(root, "HouseholdT")
    argv = case.build(root, home)
    capsys.readouterr()  # what building printed (a training run) is not the case's output
    code, out, err = run_globe(argv, capsys)
    assert code == case.code, (out, err)
    if case.code == 0:
        assert err == "", err
    else:
        lines = err.splitlines()
        assert len(lines) == 1, err  # one line, never a traceback
        if case.stderr is not None:
            assert lines[0] == case.stderr.format(root=root, home=home)
        else:
            assert case.match is not None and re.fullmatch(case.match, lines[0]), lines[0]
    if case.check is not None:
        case.check(root, home, out)
