"""Reading a report page back: the traces a plot hands to plotly, a table's cells, the self-contained check."""

from __future__ import annotations

import base64
import json
import re

import numpy as np


def plot_data(page: str, div_id: str) -> list:
    """The traces of the plot ``div_id`` as the page hands them to plotly (typed arrays decoded)."""
    match = re.search(r'Plotly\.newPlot\(\s*"' + re.escape(div_id) + r'",\s*', page)
    start = match.end()
    traces, _ = json.JSONDecoder().raw_decode(page[start:])
    return [{k: _decoded(v) for k, v in trace.items()} for trace in traces]


def _decoded(value):
    if isinstance(value, dict) and "bdata" in value:
        return np.frombuffer(base64.b64decode(value["bdata"]), dtype=np.dtype(value["dtype"])).tolist()
    if isinstance(value, dict):
        return {k: _decoded(v) for k, v in value.items()}
    return value


def table_rows(page: str, heading: str) -> list:
    """The body rows (cell texts) of the first table after ``heading``."""
    start = page.index(heading)
    block = page[page.index("<table>", start) : page.index("</table>", start)]
    rows = re.findall(r"<tr>(.*?)</tr>", block)[1:]
    return [re.findall(r"<td[^>]*>(.*?)</td>", row) for row in rows]


def assert_self_contained(page: str) -> None:
    assert page.startswith("<!DOCTYPE html>")
    assert re.search(r"<script[^>]*\bsrc\s*=", page) is None  # plotly.js inlined: no script from a network
    assert re.search(r"<link[^>]*href\s*=\s*['\"]https?:", page) is None
    assert "Plotly.newPlot" in page and 'id="summary"' in page
