"""The vocabulary of a report page's sections: what a study's ``html.py`` builds (``View``s with tables) and
``surgopt.html_report`` lays out. Here, below both, so that a study's page reads nothing of the orchestration."""
from __future__ import annotations

import html
from dataclasses import dataclass, field

import numpy as np


@dataclass
class View:
    """One section of a page: a title, a sentence of what it shows (units and frame), Plotly figures (id ->
    {data, layout}), HTML beside them (tables), data for the page's scripts (a JSON object under ``data_id``) and
    a script that uses it."""

    title: str
    note: str = ""
    figures: dict = field(default_factory=dict)
    html: str = ""
    data: dict | None = None
    data_id: str = ""
    script: str = ""


def esc(x) -> str:
    return html.escape(str(x), quote=True)


def fmt(x) -> str:
    """A cell: integers with separators, floats to 6 significant digits, NaN as 'n/a'."""
    if isinstance(x, (bool, np.bool_)):
        return "true" if x else "false"
    if isinstance(x, (int, np.integer)):
        return f"{int(x):,}"
    if isinstance(x, (float, np.floating)):
        return "n/a" if not np.isfinite(x) else f"{float(x):.6g}"
    return str(x)


def headline_cell(key: str, value):
    """A headline's value as a page shows it: an id (``best_design_id``, a key ending in ``_id``) is a name, not a
    quantity, so it is written without thousands separators (issue 56 item 4); every other value as ``fmt``."""
    if key.endswith("_id") and isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_)):
        return str(int(value))
    return value


def table_html(header, rows, table_id: str = "", sortable: bool = True, row_attrs=None) -> str:
    """A table; ``sortable``: clicking a header sorts by it (numbers as numbers); ``row_attrs(i)``: attributes of
    row i (e.g. a data index a script reads)."""
    cls = ' class="sortable"' if sortable else ""
    tid = f' id="{esc(table_id)}"' if table_id else ""
    head = "".join(f"<th>{esc(h)}</th>" for h in header)
    body = []
    for i, row in enumerate(rows):
        attrs = row_attrs(i) if row_attrs else ""
        body.append(f"<tr{attrs}>" + "".join(f"<td>{esc(fmt(v))}</td>" for v in row) + "</tr>")
    return f"<table{tid}{cls}><thead><tr>{head}</tr></thead><tbody>{''.join(body)}</tbody></table>"
