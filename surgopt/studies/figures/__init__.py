"""Figures of stored runs in the style of the papers, one module per study (matplotlib, Agg backend).

Each module's ``figures(cfg, table, out_dir, design_id)`` writes PNG files and returns their paths;
its study declares it as ``Study.figures``. Shared here: the backend, saving, and a table's columns
as plain numpy arrays.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np


def columns(table) -> dict[str, np.ndarray]:
    """An Arrow table's columns as numpy arrays (strings as object arrays, not pandas' string dtype)."""
    import pyarrow as pa

    return {name: (col.to_numpy(zero_copy_only=False) if not pa.types.is_string(col.type) else
                   np.array(col.to_pylist(), dtype=object)) for name, col in zip(table.column_names, table.columns)}


def pyplot():
    """matplotlib.pyplot on the Agg backend (no screen needed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


#: File formats ``plot --format`` offers (matplotlib writes each without extra packages).
FORMATS = ("png", "pdf", "svg")
_format = ["png"]


def set_format(fmt: str) -> None:
    """The format ``save`` writes (its path's suffix is replaced): png, pdf or svg."""
    if fmt not in FORMATS:
        raise ValueError(f"format {fmt!r}: one of {', '.join(FORMATS)}")
    _format[0] = fmt


def save(fig, path: Path) -> Path:
    path = path.with_suffix(f".{_format[0]}")
    fig.savefig(path, dpi=110, bbox_inches="tight")
    pyplot().close(fig)
    return path
