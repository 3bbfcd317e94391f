"""The README and the docs pages as a reader uses them: every code block runs, every table is what
``globe docs tables`` writes from the committed reference results, every configuration field is
documented, and the site's navigation lists every page.

Blocks by language: ``python`` is executed (in a temporary folder; blocks that read HOMER+ skip
when it is absent, and fail under CI=true); ``toml`` must be a valid GlobeConfig fragment;
``yaml`` and ``json`` must parse; in ``bash``, ``sh`` and ``console`` every ``globe ...`` line
must parse against the real command line (options, types, files: the page's titled blocks are
written beside it first). Other languages (``text``) are data, not code.
"""

from __future__ import annotations

import json
import re
import shlex
import tomllib
from pathlib import Path

import pytest
import typer
import yaml

from globe.cli.main import app
from globe.config import GlobeConfig
from globe.data.locate import resolve_data_root
from globe.errors import DataError
from globe.evaluation import docs_tables
from tests.helpers import absent

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT / "reference" / "homer_plus"
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
FENCE = re.compile(r"^```([\w-]*)([^\n]*)\n(.*?)^```[ \t]*$", re.M | re.S)
SHELLS = {"bash", "sh", "shell", "console"}
ENV_ASSIGNMENT = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*=")


def _blocks(page: Path) -> list[tuple[str, str, str, int]]:
    """``(language, info string, body, line)`` of every fenced block of ``page``."""
    text = page.read_text(encoding="utf-8")
    return [(m[1], m[2], m[3], text.count("\n", 0, m.start()) + 1) for m in FENCE.finditer(text)]


def _cases() -> list:
    cases = []
    for page in PAGES:
        for lang, _, body, line in _blocks(page):
            if lang in {"python", "toml", "yaml", "json", *SHELLS}:
                rel = page.relative_to(ROOT)
                cases.append(pytest.param(page, lang, body, id=f"{rel}:{line}:{lang}"))
    return cases


def _titled_files(page: Path, folder: Path) -> None:
    """Write the page's ``title="name"`` blocks into ``folder``: the files its commands read."""
    for _, info, body, _ in _blocks(page):
        title = re.search(r'title="([^"]+)"', info)
        if title:
            (folder / title.group(1)).write_text(body, encoding="utf-8")


def _command_lines(body: str, lang: str) -> list[list[str]]:
    """The ``globe`` command lines of a shell block, as argument lists (comments, prompts, line
    continuations and leading ``VAR=value`` assignments removed)."""
    found = []
    for raw in body.replace("\\\n", " ").splitlines():
        line = raw.strip()
        if lang == "console":
            if not line.startswith("$ "):
                continue  # output
            line = line[2:]
        words = shlex.split(line, comments=True)
        while words and ENV_ASSIGNMENT.match(words[0]):
            words = words[1:]
        if words and Path(words[0]).name == "globe":
            found.append(words[1:])
    return found


def _parse_globe(args: list[str]) -> None:
    """Parse ``globe ARGS`` exactly as the CLI does (options, types, existing files), without running it."""
    command = typer.main.get_command(app)
    ctx = command.make_context("globe", list(args))
    while hasattr(command, "resolve_command"):  # a group: go down to the subcommand
        rest = list(getattr(ctx, "_protected_args", None) or getattr(ctx, "protected_args", [])) + list(ctx.args)
        assert rest, f"'globe {' '.join(args)}' names no command"
        name, sub, remaining = command.resolve_command(ctx, rest)
        assert sub is not None and name is not None
        ctx = sub.make_context(name, remaining, parent=ctx)
        command = sub


class _AnyTagLoader(yaml.SafeLoader):
    """Home Assistant's YAML uses tags such as ``!secret`` and ``!include``: read them as plain values."""


_AnyTagLoader.add_multi_constructor("!", lambda loader, suffix, node: loader.construct_scalar(node)
                                   if isinstance(node, yaml.ScalarNode) else None)


@pytest.mark.parametrize(("page", "lang", "body"), _cases())
def test_every_code_block_runs(page, lang, body, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    if lang == "python":
        if "resolve_data_root" in body or "load_household" in body:
            try:
                resolve_data_root(None)
            except DataError as err:
                absent(f"the HOMER+ data this block reads is absent ({err}); set GLOBE_DATA")
        exec(compile(body, f"{page.name}-block", "exec"), {"__name__": "__docs__"})
        capsys.readouterr()
    elif lang == "toml":
        GlobeConfig.model_validate(tomllib.loads(body))
    elif lang == "yaml":
        assert yaml.load(body, Loader=_AnyTagLoader) is not None
    elif lang == "json":
        json.loads(body)
    else:
        _titled_files(page, tmp_path)
        for args in _command_lines(body, lang):
            _parse_globe(args)


def test_the_block_reader_finds_the_readme_quick_starts():
    langs = [lang for lang, *_ in _blocks(ROOT / "README.md")]
    assert langs.count("python") == 1 and "bash" in langs
    lines = _command_lines(next(b for lang, _, b, _ in _blocks(ROOT / "README.md") if lang == "bash"), "bash")
    assert ["reproduce"] not in lines  # `make reproduce` is not a globe command
    commands = [c for lang, _, b, _ in _blocks(ROOT / "README.md") if lang == "bash" for c in _command_lines(b, "bash")]
    assert any(c[:1] == ["predict"] for c in commands)


def test_a_command_the_cli_does_not_know_fails_to_parse(tmp_path):
    with pytest.raises(Exception, match="No such option"):
        _parse_globe(["predict", "--model-dir", str(tmp_path), "--nonsense"])
    assert _command_lines("OPENAI_BASE_URL=http://x globe evaluate --methods globe  # remote", "bash") == [
        ["evaluate", "--methods", "globe"]]


def test_a_toml_block_with_an_unknown_field_would_fail():
    with pytest.raises(ValueError):
        GlobeConfig.model_validate(tomllib.loads("[gate]\nthreshhold = 0.5\n"))


def test_every_table_is_what_the_reference_results_give():
    stale = [str(page.relative_to(ROOT)) for page, _ in docs_tables.stale_pages(ROOT, REFERENCE)]
    assert not stale, f"tables differ from {REFERENCE} in {stale}: run 'globe docs tables'"


def test_the_readme_shows_table_one_with_every_published_row():
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert "<!-- globe:table table1 -->" in readme
    from globe.evaluation.published import TABLE1

    for method in TABLE1:
        assert f"*{docs_tables.PUBLISHED_LABELS.get(method, method)} (published)*" in readme


def test_a_changed_result_makes_the_tables_stale(tmp_path):
    """The check compares numbers, not only markers: a table1.csv with one changed figure differs."""
    page = tmp_path / "README.md"
    page.write_text("<!-- globe:table calibration -->\n<!-- /globe:table -->\n", encoding="utf-8")
    fresh = docs_tables.render(page.read_text(encoding="utf-8"), REFERENCE)
    moved = tmp_path / "results"
    moved.mkdir()
    text = (REFERENCE / "calibration.csv").read_text(encoding="utf-8")
    (moved / "calibration.csv").write_text(text.replace("0.1149", "0.2149", 1), encoding="utf-8")
    assert docs_tables.render(fresh, moved) != fresh
    with pytest.raises(DataError, match="unknown table 'nope'"):
        docs_tables.render("<!-- globe:table nope -->\n<!-- /globe:table -->", REFERENCE)


def test_the_configuration_page_lists_every_field():
    page = (ROOT / "docs" / "configuration.md").read_text(encoding="utf-8")
    for section, info in GlobeConfig.model_fields.items():
        assert f"### `[{section}]`" in page, section
        for name in info.annotation.model_fields:  # type: ignore[union-attr]
            assert f"| `{name}` |" in page, f"{section}.{name}"


def test_the_site_lists_every_page_and_nothing_missing():
    config = yaml.load((ROOT / "mkdocs.yml").read_text(encoding="utf-8"), Loader=_AnyTagLoader)

    def files(nav):
        for item in nav:
            value = next(iter(item.values())) if isinstance(item, dict) else item
            yield from files(value) if isinstance(value, list) else [value]

    listed = set(files(config["nav"]))
    on_disk = {p.name for p in (ROOT / "docs").glob("*.md")}
    assert on_disk <= listed, f"pages not in the navigation: {sorted(on_disk - listed)}"
    assert config.get("strict") is True


def test_the_overview_figure_is_drawn_from_the_reference_results_and_stays_small(tmp_path):
    import subprocess
    import sys

    out = tmp_path / "overview.png"
    subprocess.run([sys.executable, str(ROOT / "tools" / "docs_figure.py"), str(REFERENCE), str(out)], check=True,
                   timeout=120, capture_output=True)
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    committed = ROOT / "docs" / "img" / "overview.png"
    assert committed.stat().st_size < 150_000 and out.stat().st_size < 150_000
