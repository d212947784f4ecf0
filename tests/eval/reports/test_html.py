"""The pieces of a self-contained page: Markdown rendered, tables sortable, images inline, nothing fetched."""

import base64
import re

import numpy as np

from eval.reports.html import CSP, Cell, image_data_uri, markdown_to_html, page, sortable_table, svg_track


def test_markdown_becomes_html_with_sortable_tables_and_inline_images(tmp_path):
    import cv2

    cv2.imwrite(str(tmp_path / "fig.png"), np.zeros((4, 6, 3), np.uint8))
    text = """# Title

A paragraph with `code <b>`, **bold** and a [link](other.md).
continued on a second line.

- one item
  continued
- two

| sequence | A | B |
|---|---:|---:|
| s1 | 0.100 [0.1, 0.2] | - |
| Avg. | 0.100 | - |

![a figure](fig.png)

```
raw <text>
```
"""
    out = markdown_to_html(text, lambda src: image_data_uri(tmp_path / src))
    assert "<h2>Title</h2>" in out  # the page's own title is the h1
    assert "<code>code &lt;b&gt;</code>" in out and "<strong>bold</strong>" in out and '<a href="other.md">' in out
    assert "continued on a second line." in out and "<li>one item continued</li><li>two</li>" in out
    assert '<table class="sortable">' in out and "<tfoot><tr><td>Avg.</td>" in out.replace("\n", "")
    assert '<td class="num" data-v="0.1">0.100 [0.1, 0.2]</td>' in out
    assert re.search(r'<img alt="a figure" src="data:image/png;base64,[A-Za-z0-9+/=]+">', out)
    assert "<pre>raw &lt;text&gt;</pre>" in out


def test_a_table_cell_keeps_its_sort_key_and_tooltip():
    html = sortable_table(["a", "b"], [[Cell("x", 2.5), Cell("n/a", None, True, "no trajectory of its own")]])
    assert '<td class="num" data-v="2.5">x</td>' in html
    assert '<td class="num" data-v="" title="no trajectory of its own">n/a</td>' in html


def test_images_inline_and_shrunk(tmp_path):
    import cv2

    cv2.imwrite(str(tmp_path / "big.png"), np.full((100, 800, 3), 200, np.uint8))
    (tmp_path / "f.svg").write_text('<svg xmlns="http://www.w3.org/2000/svg"/>')
    uri = image_data_uri(tmp_path / "big.png", max_width=200, jpeg_quality=70)
    assert uri.startswith("data:image/jpeg;base64,")
    thumb = cv2.imdecode(np.frombuffer(base64.b64decode(uri.split(",", 1)[1]), np.uint8), cv2.IMREAD_COLOR)
    assert thumb.shape == (25, 200, 3)
    assert image_data_uri(tmp_path / "f.svg").startswith("data:image/svg+xml;base64,")
    assert image_data_uri(tmp_path / "missing.png") is None and image_data_uri(tmp_path / "f.txt") is None


def test_a_track_is_an_inline_svg_with_a_scale_bar():
    t = np.linspace(0, 1, 1000)
    gt = np.column_stack([np.cos(t), np.sin(t)])
    svg = svg_track(gt, gt + 0.01, "#d55e00", max_points=100, title="x")
    assert svg.startswith("<svg") and svg.count("<polyline") == 2 and 'stroke="#d55e00"' in svg
    assert len(re.search(r'points="([^"]+)"', svg).group(1).split()) == 100 and "0.1 m</text>" in svg


def test_the_page_fetches_nothing():
    html = page("T <1>", "<p>body</p>", [("a", "A")])
    assert f'content="{CSP}"' in html and "default-src 'none'" in CSP and "img-src data:" in CSP
    assert "<title>T &lt;1&gt;</title>" in html and '<nav><a href="#a">A</a></nav>' in html
    assert not re.search(r"(src|href)=\"(https?:)?//", html) and "<link" not in html and "<script src" not in html
