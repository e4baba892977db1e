"""The HTML page the day and season reports share: sections, tables, escaping and the one
style sheet. Self-contained: no script, no external URL, so a page can be mailed, archived
or opened without network."""

from __future__ import annotations

import html
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from station import __version__


@dataclass(frozen=True)
class Section:
    """One part of the page: a heading, text, at most one picture, then tables."""

    id: str
    title: str
    intro: str  # HTML
    figure: str | None = None  # data: URI of a PNG
    alt: str = ""
    after: str = ""  # HTML
    folded: str = ""  # when set, the picture is folded under this summary (<details>)


def esc(v: Any) -> str:
    return html.escape("" if v is None else str(v))


def num(v: Any, spec: str) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "—"
    return format(v, spec)


def table(head: Sequence[str] | None, rows: Sequence[Sequence[Any]], cls: str = "") -> str:
    out = [f'<table class="{cls}">']
    if head:
        out += ["<thead><tr>", *(f"<th>{esc(h)}</th>" for h in head), "</tr></thead>"]
    out.append("<tbody>")
    for row in rows:
        out.append("<tr>" + "".join(f"<td>{esc(c)}</td>" for c in row) + "</tr>")
    out.append("</tbody></table>")
    return "".join(out)


CSS = """
body { font-family: system-ui, -apple-system, "Segoe UI", sans-serif; margin: 1.2em auto;
       max-width: 1150px; padding: 0 1em; color: #222; line-height: 1.45; }
h1 { font-size: 1.5em; margin: 0 0 0.1em 0; }
h2 { font-size: 1.25em; border-bottom: 2px solid #ddd; padding-bottom: 0.2em; margin-top: 1.6em; }
.sub { color: #666; margin-top: 0; font-size: 0.9em; }
img { max-width: 100%; height: auto; display: block; margin: 0.8em 0; }
table { border-collapse: collapse; font-size: 0.88em; margin: 0.8em 0; }
section { overflow-x: auto; }  /* a table of long item names scrolls, not the whole page */
th, td { border-bottom: 1px solid #e2e2e2; padding: 0.25em 0.7em; text-align: left;
         vertical-align: top; }
th { background: #f4f4f4; }
td { font-variant-numeric: tabular-nums; white-space: nowrap; }
td:last-child { white-space: normal; }
.warn { background: #fff4e5; border-left: 4px solid #f0a020; padding: 0.4em 0.8em; }
.err { background: #fdecea; border-left: 4px solid #d62728; padding: 0.4em 0.8em; }
pre { background: #f6f6f6; padding: 0.8em; overflow-x: auto; font-size: 0.85em; }
nav a { margin-right: 1em; }
#verdict h2 { margin-top: 0.8em; }
ul.verdicts { list-style: none; padding: 0; margin: 0.5em 0; }
ul.verdicts li { padding: 0.45em 0.8em; margin: 0.35em 0; border-left: 5px solid #9a9a9a;
                 background: #f7f7f7; font-size: 1.05em; }
ul.verdicts li.decided { border-left-color: #2ca02c; background: #eef7ee; }
ul.verdicts li.open { border-left-color: #f0a020; background: #fff7ea; }
ul.verdicts li.none { border-left-color: #9a9a9a; }
.numbers { font-variant-numeric: tabular-nums; }
details > summary { cursor: pointer; font-weight: 600; margin: 0.6em 0; }
@media print { h2 { page-break-before: auto; } img { page-break-inside: avoid; }
               details { display: block; } }
"""


def render_html(title: str, subtitle: str, sections: Sequence[Section]) -> str:
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        '<meta name="viewport" content="width=device-width, initial-scale=1">',
        f"<title>{esc(title)}</title><style>{CSS}</style></head><body>",
        f"<h1>{esc(title)}</h1><p class='sub'>{esc(subtitle)}</p>",
        "<nav>" + "".join(f'<a href="#{s.id}">{esc(s.title)}</a>' for s in sections) + "</nav>",
    ]
    for s in sections:
        parts.append(f'<section id="{s.id}"><h2>{esc(s.title)}</h2>{s.intro}')
        if s.figure:
            img = f'<figure><img src="{s.figure}" alt="{esc(s.alt)}"></figure>'
            if s.folded:
                img = f"<details><summary>{esc(s.folded)}</summary>{img}</details>"
            parts.append(img)
        parts.append(f"{s.after}</section>")
    parts.append(f"<footer><p class='sub'>station {esc(__version__)}</p></footer>")
    parts.append("</body></html>")
    return "\n".join(parts)
