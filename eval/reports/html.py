"""The pieces of a self-contained HTML page: one file that opens from disk and fetches nothing (a Content Security
Policy forbids every fetch but inline data), figures inline (PNG as data URIs, SVG as markup), every table sortable by
a click on its header (a few lines of plain JavaScript, below), and the project's Markdown reports rendered as they
are (:func:`markdown_to_html`, the subset our reports write: headings, paragraphs, lists, tables, images, code,
bold, links).

No I/O but :func:`image_data_uri` (which reads the image it embeds); the suite's page is assembled by
:mod:`eval.reports.html_report`.
"""

from __future__ import annotations

import base64
import html
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

# Nothing may be fetched: images are data URIs, style and script inline.
CSP = "default-src 'none'; img-src data:; style-src 'unsafe-inline'; script-src 'unsafe-inline'"

STYLE = """
body{font-family:system-ui,-apple-system,'Segoe UI',sans-serif;margin:0 auto;max-width:1400px;padding:0 1.2em 4em;
color:#222;line-height:1.45}
nav{position:sticky;top:0;background:#fff;border-bottom:1px solid #ddd;padding:.4em 0;z-index:2}
nav a{margin-right:1.2em}
h1{font-size:1.5em}h2{font-size:1.25em;border-bottom:1px solid #eee;margin-top:1.8em}h3{font-size:1.05em}
table{border-collapse:collapse;margin:.6em 0 1.2em;font-size:.86em}
th,td{border:1px solid #ddd;padding:.2em .5em;vertical-align:top}
td.num{text-align:right;white-space:nowrap}
table.sortable th{cursor:pointer;background:#f4f4f4;position:relative;padding-right:1.3em}
table.sortable th::after{content:'\\2195';position:absolute;right:.3em;color:#aaa}
table.sortable th[data-dir=asc]::after{content:'\\2191';color:#333}
table.sortable th[data-dir=desc]::after{content:'\\2193';color:#333}
tfoot td{border-top:2px solid #999;font-weight:600}
td a.cell{color:inherit;text-decoration:none;display:block}
td a.cell:hover{background:#eef4ff}
.range{color:#777;font-size:.85em}.paper{color:#1a5fb4;font-size:.85em}.na{color:#999}.failure{color:#c01c28;font-weight:bold}
.best{font-weight:700}
img{max-width:100%}figure{margin:.8em 0}figcaption{font-size:.85em;color:#555}
details{border:1px solid #ddd;border-radius:4px;margin:.4em 0;padding:.2em .6em}
details[open]{background:#fcfcfc}summary{cursor:pointer;font-weight:600}
.run{display:flex;flex-wrap:wrap;gap:1em;border-top:1px solid #eee;padding:.5em 0}
.run .facts{min-width:18em;max-width:30em;font-size:.86em}
pre{background:#f6f6f6;padding:.5em;overflow-x:auto;font-size:.8em;max-height:20em}
code{background:#f3f3f3;padding:0 .2em}
dl.provenance{display:grid;grid-template-columns:max-content auto;gap:.15em 1em;font-size:.9em}
dl.provenance dt{font-weight:600}
"""

# Sorting: a click on a header sorts the body rows by that column (numbers by value, from a cell's data-v or its
# text; cells without a number after all numbers either way); a second click reverses. Rows of a tfoot (Avg.) stay.
# A link to a closed <details> opens it.
SCRIPT = """
(function(){
function key(cell){var v=cell.getAttribute('data-v');if(v===null)v=cell.textContent;var x=parseFloat(v);
return isNaN(x)?v.trim().toLowerCase():x;}
function sortBy(table,col,th){var body=table.tBodies[0];var rows=Array.prototype.slice.call(body.rows);
var asc=th.getAttribute('data-dir')!=='asc';
Array.prototype.forEach.call(table.querySelectorAll('th'),function(h){h.removeAttribute('data-dir');});
th.setAttribute('data-dir',asc?'asc':'desc');
rows.sort(function(a,b){var x=key(a.cells[col]),y=key(b.cells[col]);
if(typeof x!==typeof y)return typeof x==='number'?-1:1;return (x<y?-1:x>y?1:0)*(asc?1:-1);});
rows.forEach(function(r){body.appendChild(r);});}
Array.prototype.forEach.call(document.querySelectorAll('table.sortable'),function(table){
Array.prototype.forEach.call(table.tHead.rows[0].cells,function(th,col){
th.addEventListener('click',function(){sortBy(table,col,th);});});});
function openTarget(){var id=decodeURIComponent(location.hash.slice(1));var el=id&&document.getElementById(id);
if(el&&el.tagName==='DETAILS'){el.open=true;el.scrollIntoView();}}
window.addEventListener('hashchange',openTarget);openTarget();
})();
"""


@dataclass(frozen=True)
class Cell:
    """A table cell: its ``html`` (already escaped), its sort key ``value`` (None: sorts as text, after numbers),
    ``numeric`` (right-aligned) and a ``title`` (a tooltip, e.g. why a value is missing)."""

    html: str
    value: float | None = None
    numeric: bool = True
    title: str = ""


def text_cell(text: str, numeric: bool = False) -> Cell:
    """A cell of plain ``text`` (escaped)."""
    return Cell(html.escape(text), None, numeric)


def sortable_table(headers: Sequence[str], rows: Sequence[Sequence[Cell]], footer: Sequence[Sequence[Cell]] = (),
                   caption: str = "") -> str:
    """A ``<table class="sortable">``: ``headers`` (plain text), body ``rows`` and ``footer`` rows (kept at the
    bottom when sorting: the Avg. row), ``caption`` (plain text)."""
    def row_html(cells: Sequence[Cell]) -> str:
        out = []
        for c in cells:
            attrs = ' class="num"' if c.numeric else ""
            if c.value is not None and np.isfinite(c.value):
                attrs += f' data-v="{c.value!r}"'
            elif c.numeric:
                attrs += ' data-v=""'
            if c.title:
                attrs += f' title="{html.escape(c.title)}"'
            out.append(f"<td{attrs}>{c.html}</td>")
        return "<tr>" + "".join(out) + "</tr>"

    head = "<tr>" + "".join(f"<th>{html.escape(h)}</th>" for h in headers) + "</tr>"
    parts = ['<table class="sortable">']
    if caption:
        parts.append(f"<caption>{html.escape(caption)}</caption>")
    parts += [f"<thead>{head}</thead>", "<tbody>", *map(row_html, rows), "</tbody>"]
    if footer:
        parts += ["<tfoot>", *map(row_html, footer), "</tfoot>"]
    parts.append("</table>")
    return "\n".join(parts)


def image_data_uri(path: str | Path, max_width: int | None = None, jpeg_quality: int | None = None) -> str | None:
    """The image at ``path`` as a data URI (PNG, JPEG, SVG; None when it is not there or not such an image); a
    raster wider than ``max_width`` is shrunk (area averaging) and, with ``jpeg_quality``, re-encoded as JPEG: a
    thumbnail for the page."""
    path = Path(path)
    if not path.is_file():
        return None
    suffix = path.suffix.lower()
    if suffix == ".svg":
        return "data:image/svg+xml;base64," + base64.b64encode(path.read_bytes()).decode()
    if suffix not in (".png", ".jpg", ".jpeg"):
        return None
    if max_width is None and jpeg_quality is None:
        mime = "png" if suffix == ".png" else "jpeg"
        return f"data:image/{mime};base64," + base64.b64encode(path.read_bytes()).decode()
    image = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if image is None:
        return None
    if max_width is not None and image.shape[1] > max_width:
        height = round(image.shape[0] * max_width / image.shape[1])
        image = cv2.resize(image, (max_width, height), interpolation=cv2.INTER_AREA)
    if jpeg_quality is not None:
        ok, data = cv2.imencode(".jpg", image, [cv2.IMWRITE_JPEG_QUALITY, int(jpeg_quality)])
        mime = "jpeg"
    else:
        ok, data = cv2.imencode(".png", image)
        mime = "png"
    return f"data:image/{mime};base64," + base64.b64encode(data.tobytes()).decode() if ok else None


def svg_track(gt_xy: np.ndarray, est_xy: np.ndarray, color: str, size: int = 240, max_points: int = 300,
              title: str = "") -> str:
    """An inline SVG of a top view: the ground truth (grey, dashed) and an estimate (``color``) as polylines,
    (N, 2) metres each, y up, equal scale, each thinned to at most ``max_points`` points; a scale bar in metres."""
    pts = [np.asarray(p, dtype=np.float64).reshape(-1, 2) for p in (gt_xy, est_xy)]
    allp = np.vstack([p for p in pts if p.size]) if any(p.size for p in pts) else np.zeros((1, 2))
    lo, hi = allp.min(axis=0), allp.max(axis=0)
    span = float(max(hi - lo)) or 1.0
    pad = 12.0
    scale = (size - 2 * pad) / span

    def poly(p: np.ndarray) -> str:
        if p.shape[0] > max_points:
            p = p[np.linspace(0, p.shape[0] - 1, max_points).round().astype(int)]
        xy = np.column_stack([pad + (p[:, 0] - lo[0]) * scale, size - pad - (p[:, 1] - lo[1]) * scale])
        return " ".join(f"{x:.1f},{y:.1f}" for x, y in xy)

    bar = 10 ** np.floor(np.log10(span / 2)) if span > 0 else 1.0
    parts = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{size}" height="{size}" viewBox="0 0 {size} {size}" '
             f'role="img">', f"<title>{html.escape(title)}</title>" if title else "",
             f'<rect width="{size}" height="{size}" fill="#fff" stroke="#ddd"/>']  # fmt: skip
    if pts[0].size:
        parts.append(f'<polyline points="{poly(pts[0])}" fill="none" stroke="#404040" stroke-width="1" '
                     'stroke-dasharray="4 3"/>')  # fmt: skip
    if pts[1].size:
        parts.append(f'<polyline points="{poly(pts[1])}" fill="none" stroke="{color}" stroke-width="1.4"/>')
    parts.append(f'<line x1="{pad}" y1="{size - 4}" x2="{pad + bar * scale:.1f}" y2="{size - 4}" stroke="#000"/>'
                 f'<text x="{pad + bar * scale + 3:.1f}" y="{size - 2}" font-size="9">{bar:g} m</text></svg>')
    return "".join(parts)


# ------------------------------------------------------------------------------------------------- Markdown
_INLINE = [
    (re.compile(r"!\[([^\]]*)\]\(([^)\s]+)\)"), "image"),
    (re.compile(r"\[([^\]]+)\]\(([^)\s]+)\)"), "link"),
    (re.compile(r"\*\*(.+?)\*\*"), "bold"),
]


def _inline(text: str, resolve_image: Callable[[str], str | None]) -> str:
    """One line of Markdown inline markup as HTML: `code`, **bold** (also around code), [links](url), ![images](src)
    (``src`` through ``resolve_image`` to a data URI; an image it cannot resolve becomes a link)."""
    codes: list[str] = []

    def keep(m: re.Match) -> str:
        codes.append(f"<code>{html.escape(m.group(1))}</code>")
        return f"\x00{len(codes) - 1}\x00"

    s = html.escape(re.sub(r"`([^`]*)`", keep, text), quote=False)

    def image(m: re.Match) -> str:
        uri = resolve_image(html.unescape(m.group(2)))
        if uri is None:
            return f'<a href="{m.group(2)}">{m.group(1) or m.group(2)}</a>'
        return f'<img alt="{m.group(1)}" src="{uri}">'

    s = _INLINE[0][0].sub(image, s)
    s = _INLINE[1][0].sub(lambda m: f'<a href="{m.group(2)}">{m.group(1)}</a>', s)
    s = _INLINE[2][0].sub(r"<strong>\1</strong>", s)
    return re.sub("\x00(\\d+)\x00", lambda m: codes[int(m.group(1))], s)


def _table(lines: list[str], resolve_image: Callable[[str], str | None]) -> str:
    def cells(line: str) -> list[str]:
        return [c.strip() for c in line.strip().strip("|").split("|")]

    headers = cells(lines[0])
    rows = [cells(line) for line in lines[2:]]
    body = [r for r in rows if r and r[0] != "Avg."]
    foot = [r for r in rows if r and r[0] == "Avg."]

    def cell(text: str) -> Cell:
        number = re.match(r"^\*{0,2}(-?\d+(?:\.\d+)?(?:e-?\d+)?)", text)
        return Cell(_inline(text, resolve_image), float(number.group(1)) if number else None, number is not None)

    head = [html.unescape(_inline(h, lambda _: None)) for h in headers]
    return sortable_table([re.sub(r"<[^>]+>", "", h) for h in head], [[cell(c) for c in r] for r in body],
                          [[cell(c) for c in r] for r in foot])  # fmt: skip


def markdown_to_html(text: str, resolve_image: Callable[[str], str | None] = lambda _: None) -> str:
    """Our reports' Markdown as HTML: ``#`` headings, paragraphs, ``-`` lists (indented lines continue an item),
    ``|`` tables (sortable; an ``Avg.`` row kept as the footer), fenced code, and inline code, bold, links and images
    (``resolve_image``: an image's path -> its data URI, or None)."""
    lines = text.splitlines()
    out: list[str] = []
    i = 0
    paragraph: list[str] = []

    def flush() -> None:
        if paragraph:
            out.append("<p>" + _inline(" ".join(paragraph), resolve_image) + "</p>")
            paragraph.clear()

    while i < len(lines):
        line = lines[i]
        stripped = line.strip()
        if stripped.startswith("```"):
            flush()
            j = i + 1
            while j < len(lines) and not lines[j].strip().startswith("```"):
                j += 1
            out.append("<pre>" + html.escape("\n".join(lines[i + 1:j])) + "</pre>")
            i = j + 1
            continue
        if not stripped:
            flush()
            i += 1
            continue
        heading = re.match(r"^(#{1,6})\s+(.*)$", stripped)
        if heading:
            flush()
            level = min(len(heading.group(1)) + 1, 6)  # the page's own title is the h1
            out.append(f"<h{level}>{_inline(heading.group(2), resolve_image)}</h{level}>")
            i += 1
            continue
        if stripped.startswith("|") and i + 1 < len(lines) and re.match(r"^\|[\s:|-]+\|?$", lines[i + 1].strip()):
            flush()
            j = i
            while j < len(lines) and lines[j].strip().startswith("|"):
                j += 1
            out.append(_table([raw.strip() for raw in lines[i:j]], resolve_image))
            i = j
            continue
        if stripped.startswith("- "):
            flush()
            items: list[str] = []
            while i < len(lines) and (lines[i].strip().startswith("- ") or (lines[i].startswith("  ") and items
                                                                             and lines[i].strip())):  # fmt: skip
                if lines[i].strip().startswith("- "):
                    items.append(lines[i].strip()[2:])
                else:
                    items[-1] += " " + lines[i].strip()
                i += 1
            out.append("<ul>" + "".join(f"<li>{_inline(it, resolve_image)}</li>" for it in items) + "</ul>")
            continue
        image = re.fullmatch(r"!\[([^\]]*)\]\(([^)\s]+)\)", stripped)
        if image:
            flush()
            uri = resolve_image(image.group(2))
            caption = html.escape(image.group(1))
            out.append(f'<figure><img alt="{caption}" src="{uri}"><figcaption>{caption}</figcaption></figure>'
                       if uri else f'<p><a href="{html.escape(image.group(2))}">{caption}</a></p>')  # fmt: skip
            i += 1
            continue
        paragraph.append(stripped)
        i += 1
    flush()
    return "\n".join(out)


def page(title: str, body: str, nav: Sequence[tuple[str, str]] = ()) -> str:
    """A whole self-contained page: ``title`` (plain text), ``body`` (HTML), ``nav`` links (anchor, label)."""
    links = "".join(f'<a href="#{html.escape(anchor)}">{html.escape(label)}</a>' for anchor, label in nav)
    return ("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
            f'<meta http-equiv="Content-Security-Policy" content="{CSP}">\n'
            '<meta name="viewport" content="width=device-width, initial-scale=1">\n'
            f"<title>{html.escape(title)}</title>\n<style>{STYLE}</style>\n</head>\n<body>\n"
            + (f"<nav>{links}</nav>\n" if links else "")
            + f"<h1>{html.escape(title)}</h1>\n{body}\n<script>{SCRIPT}</script>\n</body>\n</html>\n")
