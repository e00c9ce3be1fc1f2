"""What every report page shares: numbers with units, style (screen and A4 print), embedding.

Numbers are rounded for people: three significant digits with a unit prefix chosen so the
mantissa lies in [1, 1000) (``14.2 kJ``, ``830 W``), durations as ``3 min 12 s``. Tables sit in
a ``div.fit`` that scrolls sideways only if the page is narrower than the table can wrap to;
images are embedded as ``data:`` URIs so a page opens offline as one file.
"""
from __future__ import annotations

import base64
from html import escape
import io
import math

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

__all__ = ['CSS', 'data_uri', 'figure_png', 'fmt_duration', 'fmt_pct', 'fmt_si', 'img',
           'page', 'short', 'table']

CSS = """
*, *::before, *::after { box-sizing: border-box; }
body { font-family: system-ui, sans-serif; margin: 1.2em auto; padding: 0 1em;
       max-width: 1200px; color: #222; line-height: 1.4; }
h1 { font-size: 1.5em; } h2 { font-size: 1.25em; margin-top: 1.6em; }
p.answer { font-size: 1.15em; background: #e7f5ff; border-left: 4px solid #1c7ed6;
           padding: 0.5em 0.8em; }
div.fit { max-width: 100%; overflow-x: auto; }
table { border-collapse: collapse; margin: 0.5em 0 1.1em; font-size: 0.88em; }
th, td { border: 1px solid #ccc; padding: 0.2em 0.45em; vertical-align: top; }
th { background: #f1f3f5; font-weight: 600; }
td.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
td.code { font-family: ui-monospace, monospace; overflow-wrap: anywhere; }
tr.warn td { background: #fff4e6; }
tr.front td { background: #ebfbee; } tr.base td { font-style: italic; }
.status-ok { color: #2b8a3e; } .status-weak, .status-edge, .status-ambiguous { color: #c92a2a; }
img { max-width: 100%; height: auto; border: 1px solid #eee; margin: 0.3em 0; }
section { border-top: 2px solid #dee2e6; margin-top: 2em; }
.note { color: #555; font-size: 0.9em; }
details { margin: 1em 0; } summary { cursor: pointer; font-weight: 600; }
@media (max-width: 900px) { body { padding: 0 0.5em; } table { font-size: 0.78em; }
                             th, td { padding: 0.15em 0.3em; } }
@page { size: A4; margin: 14mm; }
@media print {
  body { max-width: none; margin: 0; padding: 0; font-size: 10pt; }
  div.fit { overflow: visible; }
  table { font-size: 8pt; page-break-inside: auto; } tr { page-break-inside: avoid; }
  img { max-width: 100%; page-break-inside: avoid; border: none; }
  section, h2 { page-break-after: avoid; }
  details > *:not(summary) { display: block; }
  a { color: inherit; text-decoration: none; }
}
"""

_PREFIXES = ((1e9, 'G'), (1e6, 'M'), (1e3, 'k'), (1.0, ''), (1e-3, 'm'), (1e-6, 'µ'),
             (1e-9, 'n'))


def fmt_si(value: float | None, unit: str, *, digits: int = 3, signed: bool = False) -> str:
    """``value`` in ``unit`` with a prefix and ``digits`` significant digits (``14.2 kJ``);
    an en dash for None, NaN or infinity."""
    if value is None or not math.isfinite(value):
        return '–'
    mag = abs(value)
    scale, prefix = 1.0, ''
    if 0 < mag < _PREFIXES[-1][0] * 0.9995:
        # below the smallest prefix (rounding noise of a zero, mostly): in powers of ten
        return f'{value:{"+" if signed else ""}.{max(digits - 1, 0)}e} {unit}'
    if mag > 0:
        # the first that fits: the smallest fits every magnitude left here
        scale, prefix = next((s, pre) for s, pre in _PREFIXES if mag >= s * 0.9995)
    x = value / scale
    decimals = max(0, digits - 1 - int(math.floor(math.log10(abs(x))))) if x else 0
    sign = '+' if signed and value > 0 else ''
    return f'{sign}{x:.{decimals}f} {prefix}{unit}'


def fmt_pct(value: float | None, *, signed: bool = False) -> str:
    """A percentage with sensible rounding (``62 %``, ``4.3 %``, ``0.52 %``)."""
    if value is None or not math.isfinite(value):
        return '–'
    mag = abs(value)
    decimals = 0 if mag >= 10 else 1 if mag >= 1 else 2
    return f'{value:{"+" if signed else ""}.{decimals}f} %'


def fmt_duration(seconds: float | None) -> str:
    """A duration for people: ``0.35 s``, ``42.1 s``, ``3 min 12 s``, ``2 h 05 min``."""
    if seconds is None or not math.isfinite(seconds):
        return '–'
    s = abs(seconds)
    sign = '-' if seconds < 0 else ''
    if s < 60:
        return sign + fmt_si(s, 's')
    if s < 3600:
        m, rest = divmod(round(s), 60)
        return f'{sign}{m} min {rest:02d} s'
    h, rest = divmod(round(s / 60), 60)
    return f'{sign}{h} h {rest:02d} min'


def short(text: str, limit: int = 60) -> str:
    """``text`` cut to ``limit`` characters (an ellipsis marks the cut)."""
    text = ' '.join(str(text).split())
    return text if len(text) <= limit else text[:limit - 1] + '…'


def figure_png(fig: Figure, *, dpi: int = 100) -> bytes:
    """The figure as PNG bytes (Agg canvas, no pyplot)."""
    FigureCanvasAgg(fig)
    buf = io.BytesIO()
    fig.savefig(buf, format='png', dpi=dpi)
    return buf.getvalue()


def data_uri(png: bytes) -> str:
    """A ``data:`` URI of PNG bytes (an image that needs no file beside the page)."""
    return 'data:image/png;base64,' + base64.b64encode(png).decode('ascii')


def img(png: bytes, alt: str, *, link: str | None = None) -> str:
    """An embedded ``<img>``; with ``link``, wrapped in a link to the image file."""
    tag = f'<img src="{data_uri(png)}" alt="{escape(alt)}">'
    return f'<p><a href="{escape(link)}">{tag}</a></p>' if link else f'<p>{tag}</p>'


def table(head: list[str], rows: list[list[str]], *, row_head: bool = False,
          classes: list[str] | None = None) -> str:
    """A table in a ``div.fit``; cells are HTML already (escape text before).

    Parameters
    ----------
    head
        Header cells (HTML).
    rows
        Rows of ``<td>``/``<th>`` elements, or of plain cell HTML that is wrapped in ``<td>``.
    row_head
        The first cell of each row is a header (``<th>``).
    classes
        A class per row (``''`` for none).
    """
    out = ['<div class="fit"><table>']
    if head:
        out.append('<tr>' + ''.join(f'<th>{h}</th>' for h in head) + '</tr>')
    for i, row in enumerate(rows):
        cells = []
        for j, c in enumerate(row):
            if c.startswith('<td') or c.startswith('<th'):
                cells.append(c)
            elif j == 0 and row_head:
                cells.append(f'<th style="text-align:left">{c}</th>')
            else:
                cells.append(f'<td>{c}</td>')
        cls = f' class="{classes[i]}"' if classes and classes[i] else ''
        out.append(f'<tr{cls}>' + ''.join(cells) + '</tr>')
    out.append('</table></div>')
    return '\n'.join(out)


def page(title: str, answer: str, body: str) -> str:
    """A complete HTML document: title, the one-line answer, then ``body`` (HTML)."""
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{escape(title)}</title>
<style>{CSS}</style></head>
<body>
<h1>{escape(title)}</h1>
<p class="answer">{answer}</p>
{body}
</body></html>
"""
