"""The report's HTML pieces: escaped text, tables whose numeric cells carry the file's value, figures
as inline SVG, the page's CSS (screen and A4 print). Plain strings, no template engine."""

from __future__ import annotations

import io
import math
import re
from dataclasses import dataclass
from html import escape

CSS = """
:root { font-family: "DejaVu Sans", "Liberation Sans", Arial, sans-serif; color: #111; }
body { max-width: 190mm; margin: 1.5em auto; padding: 0 1em; font-size: 10pt; line-height: 1.35; }
h1 { font-size: 16pt; margin-bottom: 0.2em; }
h2 { font-size: 12.5pt; border-bottom: 1px solid #999; margin-top: 1.6em; page-break-after: avoid;
     break-after: avoid; }
h3 { font-size: 10.5pt; margin-bottom: 0.3em; page-break-after: avoid; break-after: avoid; }
table { border-collapse: collapse; margin: 0.4em 0 1em 0; font-size: 8.5pt; page-break-inside: avoid;
        break-inside: avoid; }
caption { text-align: left; font-weight: bold; padding-bottom: 0.2em; }
th, td { border: 1px solid #bbb; padding: 2px 5px; vertical-align: top; }
th { background: #eee; text-align: left; }
td.num { text-align: right; font-variant-numeric: tabular-nums; }
figure { margin: 0.6em 0 1.2em 0; page-break-inside: avoid; break-inside: avoid; }
figure svg { display: block; max-width: 100%; height: auto; }
figcaption { font-size: 8.5pt; color: #333; }
.warnings { border: 2px solid #D55E00; background: #fff4ec; padding: 0.4em 0.8em; }
.meta td, .meta th { border: none; padding: 1px 8px 1px 0; }
.note { font-size: 8.5pt; color: #333; }
details pre { font-size: 7.5pt; background: #f6f6f6; padding: 0.5em; white-space: pre-wrap; }
@page { size: A4; margin: 14mm 12mm; }
@media print { body { max-width: none; margin: 0; padding: 0; } a { color: inherit; } }
"""


@dataclass(frozen=True, kw_only=True)
class Cell:
    """A table cell: the text shown and, for a number, the value it shows (in the shown unit)."""

    text: str
    value: float | None = None


def num(value: float, digits: int = 6) -> Cell:
    """A number shown to `digits` significant digits; NaN or infinity shown in words."""
    v = float(value)
    if math.isnan(v):
        return Cell(text="n/a", value=None)
    if math.isinf(v):
        return Cell(text="infinite" if v > 0 else "-infinite", value=v)
    return Cell(text=f"{v:.{digits}g}", value=v)


def text(value) -> Cell:
    return Cell(text=str(value))


def table(table_id: str, caption: str, headers: list[str], rows: list[list[Cell]], note: str = "") -> str:
    """A table with an id; numeric cells hold their shown value in `data-value` (repr, exact)."""
    head = "".join(f"<th>{escape(h)}</th>" for h in headers)
    body = []
    for row in rows:
        cells = []
        for c in row:
            if c.value is None:
                cells.append(f"<td>{escape(c.text)}</td>")
            else:
                cells.append(f'<td class="num" data-value="{c.value!r}">{escape(c.text)}</td>')
        body.append("<tr>" + "".join(cells) + "</tr>")
    foot = f'<p class="note">{escape(note)}</p>' if note else ""
    return (f'<table id="{escape(table_id)}"><caption>{escape(caption)}</caption><thead><tr>{head}</tr></thead>'
            f"<tbody>{''.join(body)}</tbody></table>{foot}")


_METADATA = re.compile(r"<metadata>.*?</metadata>\s*", re.DOTALL)
_XML_HEAD = re.compile(r"^\s*<\?xml[^>]*>\s*(<!DOCTYPE[^>]*>\s*)?", re.DOTALL)


def svg(fig, figure_id: str, caption: str) -> str:
    """A matplotlib figure as inline SVG inside <figure> (the XML prologue dropped; text as paths, so
    the page renders alike everywhere)."""
    import matplotlib

    buf = io.StringIO()
    with matplotlib.rc_context({"svg.fonttype": "path", "svg.hashsalt": figure_id}):
        fig.savefig(buf, format="svg")
    body = _METADATA.sub("", _XML_HEAD.sub("", buf.getvalue()))  # (the RDF block: creator, date)
    return (f'<figure id="{escape(figure_id)}">{body}<figcaption>{escape(caption)}</figcaption></figure>')


def section(section_id: str, title: str, *parts: str) -> str:
    return f'<section id="{escape(section_id)}"><h2>{escape(title)}</h2>{"".join(parts)}</section>'


def page(title: str, body: str) -> str:
    return (f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
            f'<meta name="viewport" content="width=device-width, initial-scale=1"><link rel="icon" href="data:,">'
            f"<title>{escape(title)}</title><style>{CSS}</style></head><body>{body}</body></html>\n")
