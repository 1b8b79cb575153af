"""Jinja2 environments for the report, both with autoescape on.

HTML: the usual HTML escaping; the page's CSS and script are inlined and allowed by their sha256 in
the Content-Security-Policy, so a recipe text that slipped through escaping still could not run.
Markdown: every `{{ value }}` is escaped for GitHub markdown instead (HTML specials as entities,
markdown punctuation and table pipes with backslashes), so a recipe name can neither inject HTML nor
break a table; values the writer builds as markdown on purpose are `Markup`.
"""
from __future__ import annotations

import base64
import hashlib
import re
from functools import cache
from importlib import resources
from typing import Any

from jinja2 import Environment, PackageLoader, StrictUndefined
from markupsafe import Markup

_MARKDOWN_SPECIAL = re.compile(r"([\\`*\[\]|~])")
_EDGE_UNDERSCORE = re.compile(r"(?<![A-Za-z0-9])_|_(?![A-Za-z0-9])")   # intraword _ is not emphasis on GitHub
_BLOCK_START = re.compile(r"^(\s*)(>|[#=+-]+(?=\s|$)|\d+[.)](?=\s|$))")   # heading, quote, list


def markdown_escape(value: Any) -> Markup:
    """One line of plain text, safe inside a GitHub markdown paragraph or table cell."""
    if isinstance(value, Markup):
        return value
    text = re.sub(r"\s+", " ", str(value))
    text = _MARKDOWN_SPECIAL.sub(r"\\\1", text)
    text = _EDGE_UNDERSCORE.sub(r"\\_", text)
    text = text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
    return Markup(_BLOCK_START.sub(_escape_block_marker, text))


def _escape_block_marker(match: re.Match) -> str:
    marker = match.group(2)
    if marker[0].isdigit():                       # "1." -> "1\." (a backslash before a digit shows)
        return match.group(1) + marker[:-1] + "\\" + marker[-1]
    return match.group(1) + "\\" + marker


def code_block(text: str, language: str = "") -> Markup:
    """A fenced block that shows `text` verbatim: the fence is longer than any backtick run inside."""
    longest = max((len(run) for run in re.findall(r"`+", text)), default=0)
    fence = "`" * max(3, longest + 1)
    return Markup(f"{fence}{language}\n{text.rstrip()}\n{fence}")


def code_span(text: str) -> Markup:
    """Inline code that shows `text` verbatim (one line): the backtick run around it is longer than any inside."""
    text = re.sub(r"\s+", " ", str(text))
    fence = "`" * (max((len(run) for run in re.findall(r"`+", text)), default=0) + 1)
    pad = " " if text.startswith("`") or text.endswith("`") else ""
    return Markup(f"{fence}{pad}{text}{pad}{fence}")


def csp_hash(content: str) -> str:
    return "'sha256-" + base64.b64encode(hashlib.sha256(content.encode("utf-8")).digest()).decode("ascii") + "'"


@cache
def _environments() -> tuple[Environment, Environment]:
    loader = PackageLoader("pilotlab.report", "templates")
    common = dict(loader=loader, autoescape=True, undefined=StrictUndefined, trim_blocks=True, lstrip_blocks=True,
                  keep_trailing_newline=True)
    html_env = Environment(**common)
    md_env = Environment(**common, finalize=markdown_escape)
    md_env.filters["code_block"] = code_block
    md_env.filters["code_span"] = code_span
    return html_env, md_env


def _asset(name: str) -> str:
    return resources.files("pilotlab.report").joinpath("templates", name).read_text(encoding="utf-8")


def html(template: str, context: dict[str, Any]) -> str:
    css, script = _asset("report.css"), _asset("report.js")
    assets = {"css": Markup(css), "script": Markup(script), "css_hash": csp_hash(css), "script_hash": csp_hash(script)}
    return _environments()[0].get_template(template).render(**context, **assets)


def markdown(template: str, context: dict[str, Any]) -> str:
    return _environments()[1].get_template(template).render(**context)
