"""MkDocs hook (``hooks:`` in mkdocs.yml): Sphinx cross-reference roles in docstrings, rendered.

The docstrings use Sphinx roles (``:func:`load_household```, ``:class:`~globe.errors.LLMError```),
which mkdocstrings' Markdown leaves as ``:func:<code>load_household</code>``. After each page is
converted, :func:`rewrite_roles` drops the role and links the name to its entry on the page when
there is one (the entry nearest the docstring in the package tree wins, so ``:meth:`forecast```
in a ``Forecaster`` method links to ``Forecaster.forecast``); otherwise the name stays code.
"""

from __future__ import annotations

import html
import re
from typing import Any

ROLES = ("func", "class", "meth", "mod", "data", "attr", "exc", "obj", "const", "type")
ROLE = re.compile(r":(?:py:)?(?:" + "|".join(ROLES) + r"):<code>(.*?)</code>", re.S)
ANCHOR = re.compile(r'\bid="([A-Za-z_][\w.]*)"')
TITLED = re.compile(r"^(.*?)\s*<(.+)>$", re.S)  # :func:`title <target>`


def _common(a: str, b: str) -> int:
    """How many leading dotted parts ``a`` and ``b`` share."""
    n = 0
    for x, y in zip(a.split("."), b.split(".")):
        if x != y:
            break
        n += 1
    return n


def _target(name: str, near: str, anchors: list[str]) -> str | None:
    """The anchor of ``name`` (dotted or not) on the page: the one named exactly, else the one
    ending with it that shares most with ``near`` (the entry whose docstring mentions it)."""
    if name in anchors:
        return name
    found = [a for a in anchors if a.endswith("." + name)]
    if not found:
        return None
    return min(found, key=lambda a: (-_common(a, near), len(a), a))


def rewrite_roles(page_html: str) -> str:
    """``page_html`` with every ``:role:<code>X</code>`` replaced by ``<code>X</code>``, linked to
    X's entry when the page has one."""
    anchors = [(m.start(), m.group(1)) for m in ANCHOR.finditer(page_html) if "." in m.group(1)]
    names = sorted({a for _, a in anchors})

    def replace(match: re.Match[str]) -> str:
        text = html.unescape(match.group(1)).strip()
        titled = TITLED.match(text)
        title, target = (titled.group(1), titled.group(2)) if titled else (None, text)
        link = not target.startswith("!")
        target = target.lstrip("!")
        if target.startswith("~"):
            target = target[1:]
            shown = title or target.rsplit(".", 1)[-1]
        else:
            shown = title or target
        near = next((a for pos, a in reversed(anchors) if pos < match.start()), "")
        anchor = _target(target.removesuffix("()"), near, names) if link else None
        code = f"<code>{html.escape(shown, quote=False)}</code>"
        if anchor is None:
            return code
        return f'<a class="autorefs autorefs-internal" title="{anchor}" href="#{anchor}">{code}</a>'

    return ROLE.sub(replace, page_html)


def on_page_content(content: str, **kwargs: Any) -> str:
    return rewrite_roles(content)
