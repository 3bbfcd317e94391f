"""The README and the docs pages as a reader uses them: every code block runs, every table is what
``globe docs tables`` writes from the committed reference results, every configuration field is
documented, and the site's navigation lists every page.

Blocks by language: ``python`` is executed (in a temporary folder; blocks that read HOMER+ skip
when it is absent, and fail under CI=true); ``toml`` must be a valid GlobeConfig fragment;
``yaml`` and ``json`` must parse; in ``bash``, ``sh`` and ``console`` every ``globe ...`` line
must parse against the real command line (options, types, files: the page's titled blocks are
written beside it first). Other languages (``text``) are data, not code.

The API reference, built once per session into a temporary folder, has an entry for every name of
``globe.__all__`` and for everything the pages' python blocks use from globe: imported names,
constructors (with the keywords used) and the methods called on globe's objects.
"""

from __future__ import annotations

import ast
import collections.abc
import importlib
import importlib.util
import inspect
import json
import os
import re
import shlex
import subprocess
import sys
import tomllib
import types
import typing
from dataclasses import dataclass
from html.parser import HTMLParser
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


# -- the API reference: everything the docs use is in it ---------------------------------------------


@dataclass(frozen=True)
class Need:
    """One thing a reader of the docs looks up in the API reference: ``what`` (as they would say
    it), documented under any of ``anchors`` (ids of the reference page); for a constructor called
    with arguments, the heading must show a signature with each keyword of ``params``."""

    what: str
    anchors: tuple[str, ...]
    constructor: bool = False
    params: tuple[str, ...] = ()


def _ours(obj: object) -> bool:
    return (getattr(obj, "__module__", None) or getattr(obj, "__name__", "")).split(".")[0] == "globe"


def _public_paths(obj: object, name: str | None = None) -> tuple[str, ...]:
    """Every ``module.name`` a reader can import ``obj`` as, from its own module and each package
    above it, under the name they know it by (``fit_forecaster``, not ``forecaster``)."""
    name = name or getattr(obj, "__name__", "")
    parts = obj.__module__.split(".")
    modules = [importlib.import_module(".".join(parts[:i])) for i in range(1, len(parts) + 1)]
    return tuple(f"{m.__name__}.{name}" for m in modules if getattr(m, name, None) is obj)


def _hints(obj: object) -> dict:
    """Type hints of a function or class; where some name exists only for type checkers, those
    that evaluate."""
    try:
        return typing.get_type_hints(obj)
    except Exception:
        namespace = vars(sys.modules[obj.__module__]) if obj.__module__ in sys.modules else {}
        found = {}
        for name, hint in getattr(obj, "__annotations__", {}).items():
            try:
                found[name] = eval(hint, dict(namespace)) if isinstance(hint, str) else hint
            except Exception:
                pass
        return found


def _values_of(hint) -> tuple:
    """What a type hint says a value is, as far as this check follows it: an instance of a globe
    class, or a sequence of them."""
    args = [a for a in typing.get_args(hint) if a is not Ellipsis]
    origin = typing.get_origin(hint)
    if origin in (typing.Union, types.UnionType):
        return tuple(v for a in args for v in _values_of(a))
    if origin in (list, tuple, set, frozenset, collections.abc.Sequence, collections.abc.Iterable,
                  collections.abc.Iterator):
        return (("seq", tuple(v for a in args for v in _values_of(a))),)
    return (("inst", hint),) if isinstance(hint, type) and _ours(hint) else ()


class _DocsCode:
    """Reads a python block as a reader would: which globe names it imports, which globe classes
    it builds (and with which keywords), and which methods it calls on their objects, following
    values through assignments, ``with``, ``for``, comprehensions and the return and attribute
    types of globe's own annotations. Values: ``("obj", x)`` an imported object, ``("inst", cls)``,
    ``("method", cls, name)``, ``("seq", values)``, ``("tuple", (values, ...))``."""

    def __init__(self) -> None:
        self.needs: dict[tuple, Need] = {}

    def need(self, need: Need) -> None:
        self.needs[(need.what, need.anchors, need.constructor)] = need

    def name_need(self, obj: object, what: str, name: str) -> None:
        if _ours(obj) and not inspect.ismodule(obj):
            self.need(Need(what, _public_paths(obj, name)))

    # -- statements
    def run(self, body: list[ast.stmt], env: dict) -> None:
        for node in body:
            self.stmt(node, env)

    def stmt(self, node: ast.stmt, env: dict) -> None:
        if isinstance(node, ast.ImportFrom) and (node.module or "").split(".")[0] == "globe":
            module = importlib.import_module(node.module or "")
            for alias in node.names:
                obj = getattr(module, alias.name)
                self.name_need(obj, f"{node.module}.{alias.name}", alias.name)
                env[alias.asname or alias.name] = (("obj", obj),)
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == "globe":
                    env[alias.asname or alias.name.split(".")[0]] = (("obj", importlib.import_module(
                        alias.name if alias.asname else "globe")),)
        elif isinstance(node, ast.Assign):
            values = self.expr(node.value, env)
            for target in node.targets:
                self.bind(target, values, env)
        elif isinstance(node, ast.With):
            for item in node.items:
                values = self.expr(item.context_expr, env)
                if item.optional_vars is not None:
                    self.bind(item.optional_vars, values, env)
            self.run(node.body, env)
        elif isinstance(node, ast.For):
            self.bind(node.target, self.items(self.expr(node.iter, env)), env)
            self.run(node.body + node.orelse, env)
        elif isinstance(node, ast.Try):
            self.run(node.body, env)
            for handler in node.handlers:
                caught = self.expr(handler.type, env) if handler.type is not None else ()
                if handler.name:
                    env[handler.name] = tuple(("inst", v[1]) for v in caught if isinstance(v[1], type))
                self.run(handler.body, env)
            self.run(node.orelse + node.finalbody, env)
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            inner = dict(env)
            for arg in ast.walk(node.args):
                if isinstance(arg, ast.arg):
                    inner.pop(arg.arg, None)
            self.run(node.body, inner)
        else:
            for child in ast.iter_child_nodes(node):
                if isinstance(child, ast.stmt):
                    self.stmt(child, env)
                elif isinstance(child, ast.expr):
                    self.expr(child, env)

    def bind(self, target: ast.expr, values: tuple, env: dict) -> None:
        if isinstance(target, ast.Name):
            env[target.id] = values
        elif isinstance(target, (ast.Tuple, ast.List)):
            n = len(target.elts)
            for i, element in enumerate(target.elts):
                bound = [v[1][i] for v in values if v[0] == "tuple" and len(v[1]) == n]
                self.bind(element, tuple(x for b in bound for x in b) + self.items(
                    tuple(v for v in values if v[0] == "seq")), env)

    @staticmethod
    def items(values: tuple) -> tuple:
        """What iterating over ``values`` gives."""
        out: list = []
        for v in values:
            if v[0] == "seq":
                out += v[1]
            elif v[0] == "tuple":
                out += [x for position in v[1] for x in position]
        return tuple(out)

    # -- expressions
    def expr(self, node: ast.expr, env: dict) -> tuple:
        if isinstance(node, ast.Name):
            return env.get(node.id, ())
        if isinstance(node, ast.Attribute):
            return tuple(x for v in self.expr(node.value, env) for x in self.attribute(v, node.attr))
        if isinstance(node, ast.Call):
            functions = self.expr(node.func, env)
            for arg in [*node.args, *(k.value for k in node.keywords)]:
                self.expr(arg, env)
            return tuple(x for f in functions for x in self.call(f, node))
        if isinstance(node, ast.Subscript):
            base = self.expr(node.value, env)
            self.expr(node.slice, env)
            return tuple(v for v in base if v[0] == "seq") if isinstance(node.slice, ast.Slice) else self.items(base)
        if isinstance(node, (ast.Tuple, ast.List)):
            return (("tuple", tuple(self.expr(e, env) for e in node.elts)),)
        if isinstance(node, (ast.ListComp, ast.SetComp, ast.GeneratorExp, ast.DictComp)):
            inner = dict(env)
            for generator in node.generators:
                self.bind(generator.target, self.items(self.expr(generator.iter, inner)), inner)
                for condition in generator.ifs:
                    self.expr(condition, inner)
            for part in ("elt", "key", "value"):
                if hasattr(node, part):
                    self.expr(getattr(node, part), inner)
            return ()
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.expr):
                self.expr(child, env)
        return ()

    def attribute(self, value: tuple, name: str) -> tuple:
        if value[0] == "obj" and inspect.ismodule(value[1]):
            member = getattr(value[1], name, None)
            if member is None:
                return ()
            self.name_need(member, f"{value[1].__name__}.{name}", name)
            return (("obj", member),)
        if value[0] != "inst":
            return ()
        cls = value[1]
        member = inspect.getattr_static(cls, name, None)
        if inspect.isfunction(member) or isinstance(member, (staticmethod, classmethod)):
            return (("method", cls, name),)
        if isinstance(member, property) and member.fget is not None:
            return _values_of(_hints(member.fget).get("return"))
        return _values_of(_hints(cls).get(name))

    def call(self, function: tuple, node: ast.Call) -> tuple:
        if function[0] == "method":
            _, cls, name = function
            self.need(Need(f"{cls.__name__}.{name}", tuple(f"{p}.{name}" for p in _public_paths(cls))))
            return _values_of(_hints(getattr(cls, name)).get("return"))
        if function[0] != "obj" or not _ours(function[1]):
            return ()
        obj = function[1]
        if isinstance(obj, type):
            keywords = tuple(k.arg for k in node.keywords if k.arg)
            if node.args or node.keywords:
                self.need(Need(f"{obj.__name__}({', '.join(f'{k}=...' for k in keywords) or '...'})",
                               _public_paths(obj), constructor=True, params=keywords))
            return (("inst", obj),)
        return _values_of(_hints(obj).get("return")) if callable(obj) else ()


INLINE_MEMBER = re.compile(r"`(?:globe\.)?([A-Z]\w*)\.([a-z_]\w*)(?:\(.*?\))?`")
INLINE_NAME = re.compile(r"`globe\.(\w+)`")


def _docs_needs(pages: list[Path]) -> list[Need]:
    """What the pages' python blocks use from globe, and the public names and ``Class.member``
    their prose names in code (`GlobeClient.feedback(...)`, `globe.ActivityFilter`)."""
    import globe

    reader = _DocsCode()
    for page in pages:
        for lang, _, body, _ in _blocks(page):
            if lang == "python":
                reader.run(ast.parse(body).body, {})
        prose = FENCE.sub("", page.read_text(encoding="utf-8"))
        for name in INLINE_NAME.findall(prose):
            if name in globe.__all__:
                reader.name_need(getattr(globe, name), f"globe.{name}", name)
        for cls_name, member in INLINE_MEMBER.findall(prose):
            if cls_name in globe.__all__:
                cls = getattr(globe, cls_name)
                reader.need(Need(f"{cls_name}.{member}", tuple(f"{p}.{member}" for p in _public_paths(cls))))
    return list(reader.needs.values())


def _all_needs() -> list[Need]:
    """Every public name of ``globe.__all__`` (``__version__`` aside) and what the docs use."""
    import globe

    public = [Need(f"globe.{n}", _public_paths(getattr(globe, n), n)) for n in globe.__all__ if not n.startswith("_")]
    return list(dict.fromkeys(public + _docs_needs(PAGES)))


class _Reference(HTMLParser):
    """The ids of a built page, and the text of each heading that has one (a class heading shows
    its constructor's signature)."""

    def __init__(self, text: str = "") -> None:
        super().__init__()
        self.ids: set[str] = set()
        self.headings: dict[str, str] = {}
        self._heading: tuple[str, str] | None = None
        self._text: list[str] = []
        self.feed(text)

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        anchor = dict(attrs).get("id")
        if anchor:
            self.ids.add(anchor)
            if re.fullmatch(r"h[1-6]", tag) and self._heading is None:
                self._heading, self._text = (tag, anchor), []

    def handle_endtag(self, tag: str) -> None:
        if self._heading and tag == self._heading[0]:
            self.headings[self._heading[1]] = "".join(self._text)
            self._heading = None

    def handle_data(self, data: str) -> None:
        if self._heading:
            self._text.append(data)


def _missing(needs: list[Need], page: _Reference) -> list[str]:
    """The needs the page does not meet, as readers would name them."""
    missing = []
    for need in needs:
        found = [a for a in need.anchors if a in page.ids]
        if not found:
            missing.append(f"{need.what} (no entry at any of {list(need.anchors)})")
        elif need.constructor:
            heading = page.headings.get(found[0], "")
            shown = re.findall(r"(\w+)\s*(?==|,|\))", heading.partition("(")[2])
            lacking = [p for p in need.params if p not in shown]
            if "(" not in heading or lacking:
                missing.append(f"{need.what}: the heading {heading.strip()!r} shows no constructor"
                               + (f" with {lacking}" if lacking else ""))
    return missing


def _api_page() -> str:
    """The markdown file the navigation lists as the API reference."""
    config = yaml.load((ROOT / "mkdocs.yml").read_text(encoding="utf-8"), Loader=_AnyTagLoader)
    return next(item["API reference"] for item in config["nav"] if isinstance(item, dict) and "API reference" in item)


@pytest.fixture(scope="module")
def api_reference(tmp_path_factory) -> str:
    """The API reference page's HTML, from the site built once, strictly, into a temporary folder."""
    try:
        import mkdocstrings_handlers.python  # noqa: F401
    except ImportError:
        absent("the docs extra (mkdocs, mkdocstrings[python]) is not installed: pip install -e '.[docs]'")
    out = tmp_path_factory.mktemp("site")
    built = subprocess.run([sys.executable, "-m", "mkdocs", "build", "--strict", "-q", "-d", str(out)], cwd=ROOT,
                           env={**os.environ, "NO_MKDOCS_2_WARNING": "1"}, capture_output=True, text=True, timeout=600)
    assert built.returncode == 0, built.stderr[-4000:]
    return (out / Path(_api_page()).with_suffix("") / "index.html").read_text(encoding="utf-8")


def test_the_api_reference_lists_every_public_name_and_everything_the_docs_call(api_reference):
    needs = _all_needs()
    whats = {n.what for n in needs}
    # the reader follows the quick starts' objects to their methods (a check that finds nothing proves nothing)
    assert {"globe.fit_forecaster", "GlobeClient.observe", "GlobeClient.create_household", "GlobeClient.feedback",
            "RoutineModel.fit", "ActivityModelBase.predict_proba", "ObjectModel.predict", "Forecast.useful_probability",
            "HouseholdSession.decide", "FetchPolicy(cost_useless=..., cost_missed=...)"} <= whats, sorted(whats)
    assert not _missing(needs, _Reference(api_reference)), "\n".join(_missing(needs, _Reference(api_reference)))


def test_the_reference_check_fails_on_what_the_page_lacks():
    needs = _docs_needs_of("from globe import GlobeClient, fit_forecaster\n"
                           "with GlobeClient('http://x', token='t') as client:\n"
                           "    client.observe('home1', None, 'breakfast', {})\n"
                           "    fit_forecaster(None, None).forecaster.forecast([], [], horizon=6)\n")
    assert {n.what for n in needs} == {"globe.fit_forecaster", "globe.GlobeClient", "GlobeClient(token=...)",
                                       "GlobeClient.observe", "Forecaster.forecast"}
    page = _Reference('<h3 id="globe.GlobeClient">GlobeClient(base_url, *, timeout_s=30.0)</h3>'
                      '<h3 id="globe.fit_forecaster">fit_forecaster(household, config)</h3>'
                      '<h3 id="globe.Forecaster.forecast">forecast</h3>')
    assert [m.split(" ")[0] for m in _missing(needs, page)] == ["GlobeClient(token=...):", "GlobeClient.observe"]
    page.feed('<h3 id="globe.GlobeClient.observe">observe</h3>')
    page.headings["globe.GlobeClient"] = "GlobeClient(base_url, *, token=None, timeout_s=30.0)"
    assert _missing(needs, page) == []


def _docs_needs_of(code: str) -> list[Need]:
    reader = _DocsCode()
    reader.run(ast.parse(code).body, {})
    return list(reader.needs.values())


def _hooks():
    spec = importlib.util.spec_from_file_location("docs_hooks", ROOT / "docs" / "hooks.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_sphinx_roles_in_docstrings_become_code_linked_to_their_entry():
    page = ('<h3 id="globe.Forecaster">Forecaster</h3><h3 id="globe.Forecaster.forecast">forecast</h3>'
            '<h3 id="globe.FetchPolicy.forecast">forecast</h3><h3 id="globe.Forecaster.forecast_many">x</h3>'
            "<p>:meth:<code>forecast</code> for many; see :func:<code>household_dir</code> and "
            ":class:<code>~globe.errors.LLMError</code>, :py:mod:<code>globe.models</code>.</p>")
    out = _hooks().rewrite_roles(page)
    assert ":meth:" not in out and ":func:" not in out and ":class:" not in out and ":py:mod:" not in out
    link = '<a class="autorefs autorefs-internal" title="globe.Forecaster.forecast" href="#globe.Forecaster.forecast">'
    assert link + "<code>forecast</code></a> for many" in out
    assert "see <code>household_dir</code> and <code>LLMError</code>, <code>globe.models</code>." in out


def test_no_sphinx_role_is_left_in_the_built_reference(api_reference):
    text = re.sub(r"<[^>]+>", "", api_reference)
    left = re.findall(r".{0,40}:(?:py:)?(?:func|class|meth|mod|data|attr|exc|obj):`?\w.{0,40}", text)
    assert not left, left[:5]
