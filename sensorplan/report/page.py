"""The HTML kit of the report: inline styles, embedded PNG figures with their reading guides, tables,
numbers, and the page that holds the sections.

Figures are embedded as base64 PNG, styles inline, no network needed to view the file.
"""

import base64
import html
import io
from datetime import datetime, timezone

import numpy as np

__all__ = ["figure_html", "table_html", "fmt", "render_page"]

_CSS = """
body{font-family:system-ui,-apple-system,Segoe UI,Helvetica,Arial,sans-serif;max-width:980px;margin:2em auto;
color:#1d1d1f;line-height:1.45;padding:0 1em}
h1{font-size:1.7em;margin-bottom:.2em}h2{border-bottom:2px solid #ddd;padding-bottom:.2em;margin-top:1.8em}
table{border-collapse:collapse;margin:.6em 0 1em;font-size:.92em}
th,td{border:1px solid #ccc;padding:.25em .6em;text-align:right}th{background:#f3f3f3}
td.l,th.l{text-align:left}figure{margin:1em 0}figure img{max-width:100%;border:1px solid #eee}
figcaption{font-size:.9em;color:#444}figcaption b{color:#1d1d1f}.note{color:#555;font-size:.9em}
.verdict{background:#f6f8ff;border-left:4px solid #4a6cf7;padding:.5em .8em}
.conclusion{background:#f4faf4;border-left:4px solid #2e8b57;padding:.6em .9em;font-size:1.02em}
.conclusion.warn{background:#fdf6ec;border-left-color:#d9822b}
.warn{color:#a33}
@media print{body{max-width:none;margin:0;padding:0;font-size:10pt;color:#000}nav{display:none}
h2{page-break-after:avoid;break-after:avoid}figure,table{page-break-inside:avoid;break-inside:avoid}
section{page-break-before:auto}figure img{max-width:100%;border:none}a{color:#000;text-decoration:none}
.conclusion,.verdict{background:none}}
"""

_SCRIPT = """window.addEventListener('load',function(){var im=document.images,ok=0;
for(var i=0;i<im.length;i++){if(im[i].complete&&im[i].naturalWidth>0){ok++;}}
document.body.setAttribute('data-images-loaded',ok+'/'+im.length);});"""


def _png(ax_or_fig):
    fig = getattr(ax_or_fig, "figure", ax_or_fig)
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    return base64.b64encode(buf.getvalue()).decode("ascii")


def figure_html(ax, title, guide):
    """The figure of ``ax`` as an embedded PNG, captioned with its title and a one-sentence reading guide."""
    return (f'<figure><img alt="{html.escape(title)}" src="data:image/png;base64,{_png(ax)}">'
            f"<figcaption><b>{html.escape(title)}.</b> Reading guide: {html.escape(guide)}</figcaption></figure>")


def table_html(header, rows, left=1):
    """An HTML table of ``rows`` under ``header``, its first ``left`` columns aligned left, every cell escaped."""
    head = "".join(f'<th class="{"l" if i < left else ""}">{html.escape(str(h))}</th>' for i, h in enumerate(header))
    body = "".join("<tr>" + "".join(f'<td class="{"l" if i < left else ""}">{html.escape(str(c))}</td>'
                                    for i, c in enumerate(row)) + "</tr>" for row in rows)
    return f"<table><tr>{head}</tr>{body}</table>"


def fmt(x, digits=4):
    """``x`` with ``digits`` significant digits; "n/a" for None or a non-finite float."""
    if x is None or (isinstance(x, float) and not np.isfinite(x)):
        return "n/a"
    return f"{x:.{digits}g}"


def render_page(case, sections):
    """The whole page: title, generation stamp, table of contents and the (title, HTML) ``sections``."""
    stamp = datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    toc = "".join(f'<li><a href="#s{i}">{html.escape(t)}</a></li>' for i, (t, _) in enumerate(sections))
    body = "".join(f'<section id="s{i}"><h2>{html.escape(t)}</h2>{content}</section>'
                   for i, (t, content) in enumerate(sections))
    return (f'<!DOCTYPE html><html lang="en"><head><meta charset="utf-8"><title>sensorplan report: '
            f"{html.escape(case.name)}</title><style>{_CSS}</style><script>{_SCRIPT}</script></head><body>"
            f"<h1>sensorplan report: {html.escape(case.name)}</h1>"
            f'<p class="note">Generated {stamp} by sensorplan. Units: m, N, N m^2; tilt in µrad, '
            "deflection in mm.</p>"
            f"<nav><ol>{toc}</ol></nav>{body}</body></html>")
