"""Tiny HTML building blocks: escaped tables, base64-embedded images (no external requests) and
numbers formatted for a cell."""

from __future__ import annotations

import base64
import html
import re
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

from graspstab.figures.presentation import UNDEFINED, finite


def esc(value: Any) -> str:
    """Escape any value for HTML text."""
    return html.escape(str(value))


def fmt(value: Any, spec: str = ".1f", scale: float = 1.0) -> str:
    """A number formatted by ``spec`` (times ``scale``), or "undefined" for None/NaN (strict
    JSON stores an undefined value as null)."""
    return format(float(value) * scale, spec) if finite(value) else UNDEFINED


def table(
    headers: Sequence[str], rows: Iterable[Sequence[Any]], caption: str = "", cls: str = ""
) -> str:
    """An HTML table with escaped cells, in a box that scrolls sideways when the table is wider
    than the page (rather than widening the page); ``cls`` is a CSS class (``text``: left-align
    every column)."""
    head = "".join(f"<th>{esc(h)}</th>" for h in headers)
    body = "".join("<tr>" + "".join(f"<td>{esc(c)}</td>" for c in row) + "</tr>" for row in rows)
    cap = f"<caption>{esc(caption)}</caption>" if caption else ""
    klass = f' class="{esc(cls)}"' if cls else ""
    return (
        f'<div class="wide"><table{klass}>{cap}<thead><tr>{head}</tr></thead>'
        f"<tbody>{body}</tbody></table></div>"
    )


def image(path: Path | bytes, alt: str, caption: str = "", anchor: str = "", toc: str = "") -> str:
    """A PNG (file or bytes) embedded as a data URI inside a captioned figure; ``anchor`` gives
    the figure a stable id, ``toc`` its entry in the table of contents."""
    raw = path if isinstance(path, bytes) else Path(path).read_bytes()
    data = base64.b64encode(raw).decode("ascii")
    cap = f"<figcaption>{esc(caption)}</figcaption>" if caption else ""
    return (
        f'<figure{_ids(anchor, toc)}><img alt="{esc(alt)}" '
        f'src="data:image/png;base64,{data}">{cap}</figure>'
    )


def missing_figure(anchor: str, toc: str, text: str) -> str:
    """A figure slot that says why its figure is absent, so its id (and link) stays valid."""
    return f'<figure{_ids(anchor, toc)}><p class="note">{text}</p></figure>'


def _ids(anchor: str, toc: str) -> str:
    return (f' id="{esc(anchor)}"' if anchor else "") + (f' data-toc="{esc(toc)}"' if toc else "")


def heading(level: int, anchor: str, title: str) -> str:
    """A section heading with a stable id (links into the report must not break)."""
    return f'<h{level} id="{esc(anchor)}">{esc(title)}</h{level}>'


_TOC_ITEM = re.compile(
    r'<h([23]) id="([^"]+)">(.*?)</h\1>|<figure id="([^"]+)" data-toc="([^"]+)">', re.S
)


def toc(body: str) -> str:
    """A table of contents read back from the assembled body (h2, h3 and figures with a
    ``data-toc`` title), so it cannot list a section the report does not have."""
    items: list[tuple[str, str, list[str]]] = []
    for level, hid, title, fid, ftitle in _TOC_ITEM.findall(body):
        link = f'<a href="#{hid or fid}">{title or ftitle}</a>'
        if level == "2":
            items.append((hid, link, []))
        elif items:
            items[-1][2].append(f"<li>{link}</li>")
        else:
            items.append((hid or fid, link, []))
    lis = "".join(
        f"<li>{link}" + (f"<ul>{''.join(sub)}</ul>" if sub else "") + "</li>"
        for _, link, sub in items
    )
    return f'<nav id="contents"><h2>Contents</h2><ul>{lis}</ul></nav>'


STYLE = """
body{font-family:system-ui,-apple-system,Segoe UI,sans-serif;max-width:1100px;margin:2em auto;
padding:0 1em;color:#222;line-height:1.45}
h1{border-bottom:2px solid #444}h2{border-bottom:1px solid #bbb;margin-top:2em}
table{border-collapse:collapse;margin:1em 0;font-size:0.92em}
th,td{border:1px solid #ccc;padding:3px 8px;text-align:right}th{background:#f0f0f0}
td:first-child,th:first-child{text-align:left}caption{caption-side:top;font-weight:600;
text-align:left;padding:4px 0}
figure{margin:1em 0}img{max-width:100%;border:1px solid #ddd}figcaption{font-size:0.9em;color:#555}
.note{background:#fff7e0;border-left:4px solid #e0a800;padding:0.6em 1em}
pre{background:#f6f6f6;padding:1em;overflow-x:auto;font-size:0.85em}
.wide{overflow-x:auto}table.text td,table.text th{text-align:left}
nav ul{margin:0.2em 0;padding-left:1.4em;columns:2}nav ul ul{columns:1;font-size:0.92em}
nav li{break-inside:avoid}
"""


def page(title: str, sections: Sequence[str], contents: bool = False) -> str:
    """The whole document: one file, inline CSS, no scripts, no external resources; with
    ``contents``, a table of contents (see :func:`toc`) under the title."""
    body = "\n".join(sections)
    return (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        f'<meta name="viewport" content="width=device-width, initial-scale=1">'
        # no favicon request: a self-contained file must not ask the browser for anything
        '<link rel="icon" href="data:,">'
        f"<title>{esc(title)}</title><style>{STYLE}</style></head><body>"
        f"<h1>{esc(title)}</h1>" + (toc(body) if contents else "") + body + "</body></html>\n"
    )
