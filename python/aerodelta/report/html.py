"""Assembly of the report: one self-contained HTML file (inline CSS, embedded images, no
scripts, nothing fetched from the network), summary page first."""

from __future__ import annotations

import datetime as _dt
import html
import math
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import polars as pl

from aerodelta.exceptions import InvalidInputError


@dataclass
class Section:
    """One chapter of the report.

    Attributes
    ----------
    key
        Anchor (``id``) of the section.
    title
        Heading.
    body
        HTML fragments in order (paragraphs, tables, figures).
    summary
        ``(label, value)`` pairs shown on the summary page (value is HTML).
    seconds
        Time spent building the section, s.
    tables
        Result tables (polars frames) kept for the caller and tests.
    """

    key: str
    title: str
    body: list[str] = field(default_factory=list)
    summary: list[tuple[str, str]] = field(default_factory=list)
    seconds: float = 0.0
    tables: dict[str, Any] = field(default_factory=dict)


def esc(x: object) -> str:
    """HTML-escaped ``str(x)``."""
    return html.escape(str(x))


def p(text: str) -> str:
    """A paragraph of (already safe) HTML."""
    return f"<p>{text}</p>"


def fmt(v: object, spec: str = ".4g") -> str:
    """A number formatted for a table (blank for NaN/None)."""
    if v is None:
        return ""
    if isinstance(v, bool):
        return "yes" if v else "no"
    if isinstance(v, float):
        return "" if math.isnan(v) else format(v, spec)
    if isinstance(v, int):
        return str(v)
    return esc(v)


def table(
    df: pl.DataFrame,
    *,
    formats: Mapping[str, str] | None = None,
    headers: Mapping[str, str] | None = None,
    row_class: Callable[[dict[str, Any]], str] | None = None,
    max_rows: int | None = None,
) -> str:
    """An HTML table of a frame (numbers formatted with ``formats[col]``, default ``.4g``)."""
    formats = formats or {}
    headers = headers or {}
    head = "".join(f"<th>{esc(headers.get(c, c))}</th>" for c in df.columns)
    rows = []
    for i, r in enumerate(df.iter_rows(named=True)):
        if max_rows is not None and i >= max_rows:
            break
        cls = row_class(r) if row_class else ""
        cells = "".join(f"<td>{fmt(r[c], formats.get(c, '.4g'))}</td>" for c in df.columns)
        rows.append(f'<tr class="{cls}">{cells}</tr>' if cls else f"<tr>{cells}</tr>")
    more = ""
    if max_rows is not None and df.height > max_rows:
        more = f'<p class="note">{df.height - max_rows} more rows not shown.</p>'
    return f"<table><thead><tr>{head}</tr></thead><tbody>{''.join(rows)}</tbody></table>{more}"


def details(summary: str, inner: str) -> str:
    """A collapsed block (HTML ``<details>``, no script)."""
    return f"<details><summary>{esc(summary)}</summary>{inner}</details>"


#: The page style shared by the report and the evidence pack (header, navigation, sections,
#: tables); each adds its own cell and row rules.
BASE_CSS = """
body{font:14px/1.45 system-ui,-apple-system,'Segoe UI',Roboto,sans-serif;margin:0;color:#222;
background:#fafafa}
header{background:#1f3b57;color:#fff;padding:14px 28px}
header h1{margin:0;font-size:22px} header p{margin:4px 0 0;opacity:.85}
nav{position:sticky;top:0;background:#eef2f6;padding:6px 28px;border-bottom:1px solid #ccd;
z-index:2;font-size:13px}
nav a{margin-right:14px;color:#1f3b57;text-decoration:none}
main{max-width:1180px;margin:0 auto;padding:8px 28px 40px}
section{background:#fff;border:1px solid #e1e4e8;border-radius:6px;padding:6px 20px 14px;
margin:16px 0}
h2{border-bottom:2px solid #1f3b57;padding-bottom:4px;font-size:19px}
h3{font-size:15px;margin:18px 0 6px}
table{border-collapse:collapse;margin:8px 0;font-size:12.5px}
"""

_CSS = (
    BASE_CSS
    + """th,td{border:1px solid #d0d7de;padding:3px 8px;text-align:right}
th{background:#f0f3f6} td:first-child,th:first-child{text-align:left}
tr.held td{background:#fff8e1} tr.bad td{background:#fdecea} tr.good td{background:#e8f5e9}
figure{margin:10px 0} figure img{max-width:100%;height:auto;border:1px solid #eee}
figcaption{font-size:12.5px;color:#555;margin-top:3px}
.cards{display:flex;flex-wrap:wrap;gap:10px}
.card{flex:1 1 210px;border:1px solid #d0d7de;border-radius:6px;padding:8px 12px;background:#f8fafc}
.card>b{display:block;font-size:12px;color:#555;font-weight:600}
.card span{font-size:16px}
.note{color:#666;font-size:12.5px}
.ok{color:#1b7f3b;font-weight:600} .fail{color:#b42318;font-weight:600}
details{margin:6px 0} summary{cursor:pointer;color:#1f3b57}
"""
)


def generated_at() -> _dt.datetime:
    """The report's generation time (UTC): now, or ``SOURCE_DATE_EPOCH`` (s since 1970, the
    reproducible-builds.org convention, which matplotlib follows too) when it is set, so the
    same inputs give the same bytes."""
    epoch = os.environ.get("SOURCE_DATE_EPOCH", "").strip()
    if not epoch:
        return _dt.datetime.now(_dt.timezone.utc)
    try:
        return _dt.datetime.fromtimestamp(int(epoch), _dt.timezone.utc)
    except (ValueError, OverflowError, OSError):
        raise InvalidInputError(
            f"SOURCE_DATE_EPOCH={epoch!r} is not a time in whole seconds since 1970-01-01 UTC; "
            "set it to an integer such as 1700000000, or unset it"
        ) from None


def page(
    title: str,
    subtitle: str,
    intro: str,
    sections: Sequence[Section],
    *,
    generated: _dt.datetime | None = None,
) -> str:
    """The whole report: header, navigation, summary page, then each section; ``generated``
    (default :func:`generated_at`) is stamped in the header."""
    nav = "".join(f'<a href="#{esc(s.key)}">{esc(s.title)}</a>' for s in sections)
    cards = []
    for s in sections:
        for label, value in s.summary:
            cards.append(
                f'<div class="card"><b><a href="#{esc(s.key)}">{esc(s.title)}</a> · '
                f"{esc(label)}</b><span>{value}</span></div>"
            )
    summary = (
        '<section id="summary"><h2>Summary</h2>'
        f'{intro}<div class="cards">{"".join(cards)}</div></section>'
    )
    body = "".join(
        f'<section id="{esc(s.key)}"><h2>{esc(s.title)}</h2>{"".join(s.body)}</section>'
        for s in sections
    )
    stamp = (generated or generated_at()).strftime("%Y-%m-%d %H:%M UTC")
    return (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        '<meta name="viewport" content="width=device-width, initial-scale=1">'
        f"<title>{esc(title)}</title><style>{_CSS}</style></head><body>"
        f"<header><h1>{esc(title)}</h1><p>{esc(subtitle)} · generated {stamp}</p></header>"
        f'<nav><a href="#summary">Summary</a>{nav}</nav><main>{summary}{body}</main>'
        "</body></html>\n"
    )
