"""The skeleton of a report page: a summary at the top, foldable sections, plotly figures and small tables.

The plotly.js bundle is inlined once in the page's head, so the file opens from disk with no network; every
figure is a ``<div class="psdm-plot">`` whose data are the figure's JSON (a test or a reader can take the
numbers back out). A figure inside a closed ``<details>`` is resized when its section is opened.

The bundle is plotly's own "basic" partial bundle (scatter, bar, pie: every trace the reports draw; 1.2 MB
instead of the full 4.8 MB that the plotly package ships), kept gzipped beside this module
(``assets/plotly-basic.min.js.gz``, from the npm package ``plotly.js-basic-dist-min``, MIT, the same
plotly.js version as the pip package's). A page with a trace type outside it gets the full bundle.
"""

from __future__ import annotations

import gzip
import html
import re
from dataclasses import dataclass, field
from pathlib import Path

from psdm_casadi.fileio import atomic_write

#: The trace types of plotly's basic partial bundle (what the reports draw).
BASIC_TRACES = frozenset({"scatter", "bar", "pie"})
BASIC_BUNDLE = Path(__file__).with_name("assets") / "plotly-basic.min.js.gz"
#: The version line of the bundle's header comment (``plotly.js (basic - minified) v4.1.1``).
BUNDLE_VERSION = re.compile(r"plotly\.js \(basic - minified\) v(\d+\.\d+\.\d+)")
#: The class of a figure whose traces the basic bundle cannot draw (the page then inlines the full bundle).
NEEDS_FULL = "psdm-needs-full-plotly"

STYLE = """
body { font-family: system-ui, sans-serif; margin: 1.5em auto; max-width: 1100px; color: #222; }
h1 { font-size: 1.5em; } summary { font-size: 1.15em; font-weight: 600; cursor: pointer; padding: 0.3em 0; }
details { border-top: 1px solid #ddd; padding: 0.3em 0; }
.summary { background: #f6f8fa; border-left: 4px solid #888; padding: 0.6em 1em; }
.summary li { margin: 0.25em 0; } .good { color: #1a7f37; } .warn { color: #9a6700; } .bad { color: #cf222e; }
table { border-collapse: collapse; margin: 0.5em 0; font-size: 0.9em; }
td, th { border: 1px solid #ccc; padding: 0.2em 0.5em; text-align: right; } th { background: #f0f0f0; }
td.text { text-align: left; }
"""

#: Resize the plots of a section when it is opened (they were laid out while hidden).
RESIZE_SCRIPT = """
document.querySelectorAll('details').forEach(function (d) {
  d.addEventListener('toggle', function () {
    if (d.open) { d.querySelectorAll('.psdm-plot .js-plotly-plot').forEach(function (p) { Plotly.Plots.resize(p); }); }
  });
});
"""


@dataclass(frozen=True)
class SummaryLine:
    """One line of the summary: its text and its tone (``good``, ``warn``, ``bad`` or ``""``)."""

    text: str
    tone: str = ""


@dataclass
class Page:
    """A report page under construction: ``title``, the summary lines, then (title, body HTML, open) sections."""

    title: str
    summary: list = field(default_factory=list)
    sections: list = field(default_factory=list)

    def say(self, text: str, tone: str = "") -> None:
        """Add a line to the summary."""
        self.summary.append(SummaryLine(text, tone))

    def section(self, title: str, body: str, open_: bool = False) -> None:
        """Add a foldable section (closed unless ``open_``)."""
        self.sections.append((title, body, open_))

    def to_html(self) -> str:
        """The whole page: plotly.js inlined once in the head, the summary, the sections."""
        items = "".join(f'<li class="{s.tone}">{html.escape(s.text)}</li>' for s in self.summary)
        parts = [
            "<!DOCTYPE html><html><head><meta charset='utf-8'>",
            f"<title>{html.escape(self.title)}</title><style>{STYLE}</style>",
            f"<script type='text/javascript'>{plotly_bundle(self.needs_full_bundle())}</script></head><body>",
            f"<h1>{html.escape(self.title)}</h1>",
            f'<div class="summary" id="summary"><h2>Summary</h2><ul>{items}</ul></div>',
        ]
        for title, body, open_ in self.sections:
            parts.append(f"<details{' open' if open_ else ''}><summary>{html.escape(title)}</summary>{body}</details>")
        parts.append(f"<script>{RESIZE_SCRIPT}</script></body></html>")
        return "\n".join(parts)

    def needs_full_bundle(self) -> bool:
        """Whether a figure of the page has a trace type outside the basic bundle."""
        return any(NEEDS_FULL in body for _, body, _ in self.sections)

    def write(self, path, overwrite: bool = False) -> Path:
        """Write the page to ``path`` atomically (refused if it exists, unless ``overwrite``); returns it."""
        text = self.to_html()
        return atomic_write(path, lambda handle: handle.write(text), overwrite=overwrite)


def figure_div(figure, div_id: str, css_class: str = "") -> str:
    """A plotly figure as a ``<div class="psdm-plot ...">`` (no plotly.js: the page's head holds it)."""
    import plotly.io as pio

    inner = pio.to_html(figure, full_html=False, include_plotlyjs=False, div_id=div_id, config={"responsive": True})
    types = {trace.type for trace in figure.data}
    if not types <= BASIC_TRACES:
        css_class = f"{css_class} {NEEDS_FULL}".strip()
    return f'<div class="psdm-plot {css_class}">{inner}</div>'


def plotly_bundle(full: bool = False) -> str:
    """The plotly.js source to inline: the basic partial bundle, or the plotly package's full one.

    The full one when ``full``, or when the installed plotly package speaks another major version of
    plotly.js than the basic bundle (its figures' JSON might use what the bundle does not read)."""
    from plotly.offline import get_plotlyjs, get_plotlyjs_version

    basic = gzip.decompress(BASIC_BUNDLE.read_bytes()).decode("utf-8")
    found = BUNDLE_VERSION.search(basic[:200])
    if full or found is None or found.group(1).split(".")[0] != get_plotlyjs_version().split(".")[0]:
        return get_plotlyjs()
    return basic


def table(headers, rows, text_columns: int = 1) -> str:
    """An HTML table; the first ``text_columns`` columns left-aligned, cells escaped, floats as ``%.4g``."""
    head = "".join(f"<th>{html.escape(str(h))}</th>" for h in headers)
    body = []
    for row in rows:
        cells = []
        for k, cell in enumerate(row):
            text = f"{cell:.4g}" if isinstance(cell, float) else str(cell)
            align = ' class="text"' if k < text_columns else ""
            cells.append(f"<td{align}>{html.escape(text)}</td>")
        body.append("<tr>" + "".join(cells) + "</tr>")
    return f"<table><tr>{head}</tr>{''.join(body)}</table>"


def paragraphs(texts) -> str:
    """A bullet list of escaped sentences ("" for none)."""
    items = "".join(f"<li>{html.escape(str(t))}</li>" for t in texts)
    return f"<ul>{items}</ul>" if items else ""
