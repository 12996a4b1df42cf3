"""A run's rows, part by part: what summaries read so that memory stays flat as the work grows.

``Parts`` yields one verified Arrow table per stored part (or wraps one in-memory table) and offers
the streaming reductions summaries need: counts, the top rows by a column, one column whole, and
rows matching a filter. Only one part (plus the running top-k) is in memory at a time; a whole
column is 8 bytes a row.
"""
from __future__ import annotations

from typing import Callable, Iterable, Iterator

import numpy as np


class Parts:
    """Re-iterable sequence of Arrow tables sharing one schema."""

    def __init__(self, tables: Callable[..., Iterable], num_rows: int, schema):
        # tables(columns=None, which=None): the parts (only those at the positions ``which``, in order, if given),
        # with only these columns if given
        self._tables = tables
        self.num_rows = num_rows
        self.schema = schema

    @classmethod
    def of_table(cls, table) -> "Parts":
        """One in-memory table as Parts (tests, the Python API, small runs)."""
        def tables(columns=None, which=None):
            return [table if columns is None else table.select(columns)] if which is None or 0 in which else []

        return cls(tables, table.num_rows, table.schema)

    def watched(self, on_rows: Callable[[int], None]) -> "Parts":
        """The same parts, calling ``on_rows(n)`` as each part of n rows is read (a progress display)."""
        def tables(columns=None, which=None):
            for t in self._tables(columns, which):
                on_rows(t.num_rows)
                yield t

        return Parts(tables, self.num_rows, self.schema)

    def at(self, which: list[int]) -> Iterator:
        """The whole parts at these positions (0: the first part), in that order."""
        return iter(self._tables(None, sorted(which)))

    def __iter__(self) -> Iterator:
        return iter(self._tables())

    def only(self, columns: list[str] | None) -> Iterator:
        """The parts with only ``columns`` read (Parquet reads just those: a pass over one column is cheap)."""
        return iter(self._tables(columns))

    def table(self):
        """Everything as one table (only where the whole run must be in memory, e.g. baselines)."""
        import pyarrow as pa

        tables = list(self)
        return pa.concat_tables(tables) if tables else self.schema.empty_table()

    def count(self, predicate: Callable, columns: list[str] | None = None) -> int:
        """Rows where ``predicate(part)`` (a boolean array or Arrow mask) is true; ``columns``: the ones
        the predicate reads (only those are read), or None for all."""
        return int(sum(int(np.count_nonzero(_np(predicate(t)))) for t in self.only(columns)))

    def column(self, name: str, where: Callable | None = None) -> np.ndarray:
        """One column over all parts (optionally only rows where ``where(part)``) as a numpy array."""
        chunks = []
        for t in (self.only([name]) if where is None else self):
            v = t[name].to_numpy(zero_copy_only=False)
            chunks.append(v[_np(where(t))] if where is not None else v)
        return np.concatenate(chunks) if chunks else np.zeros(0)

    def top(self, column: str, k: int, where: Callable | None = None, ascending: bool = False):
        """The k rows with the largest ``column`` (``ascending``: the smallest; first occurrence wins ties, as a
        stable sort of the whole table would), over rows where ``where(part)`` if given; an Arrow table, best
        first."""
        import pyarrow as pa

        best, offset = None, 0
        for t in self:
            n = t.num_rows
            if where is not None:
                mask = _np(where(t))
                pos = np.flatnonzero(mask)
                t = t.filter(pa.array(mask))
            else:
                pos = np.arange(n)
            cand = t.append_column("__order", pa.array(pos + offset, pa.int64()))
            offset += n
            best = cand if best is None else pa.concat_tables([best, cand])
            best = _top_k(best, column, k, ascending)
        if best is None:
            return self.schema.empty_table()
        return best.drop_columns(["__order"])

    def scan(self, column: str, k: int, ascending: bool = False, where: Callable | None = None,
             where_columns: tuple[str, ...] | None = None, top_where: bool = False):
        """What a summary shows of ``column``: (its k largest rows as ``top`` gives them, unfiltered, or with
        ``top_where`` among the rows where ``where(part)`` only; the column whole; the column over rows where
        ``where(part)``, or None). ``where_columns``: the columns ``where`` reads, when known: then one pass reads
        ``column`` and those alone, and a second only the parts that hold the k rows (a 2.2 M-row port-place run:
        2 of 45 columns, then a few parts); else one pass reads every column of every part."""
        if where is None or where_columns is not None:
            return self._scan_narrow(column, k, ascending, where, where_columns or (), top_where)
        import pyarrow as pa

        best, offset, values, kept = None, 0, [], []
        for t in self:
            v = t[column].to_numpy(zero_copy_only=False)
            values.append(v)
            if where is not None:
                kept.append(v[_np(where(t))])
            cand = t.append_column("__order", pa.array(np.arange(offset, offset + t.num_rows), pa.int64()))
            offset += t.num_rows
            if top_where and where is not None:
                cand = cand.filter(pa.array(_np(where(t))))
            best = _top_k(cand if best is None else pa.concat_tables([best, cand]), column, k, ascending)
        top = self.schema.empty_table() if best is None else best.drop_columns(["__order"])
        whole = np.concatenate(values) if values else np.zeros(0)
        return top, whole, (np.concatenate(kept) if kept else np.zeros(0)) if where is not None else None

    def _scan_narrow(self, column: str, k: int, ascending: bool, where: Callable | None, where_columns,
                     top_where: bool = False) -> tuple:
        values, kept, sizes, masks = [], [], [], []
        for t in self.only(list(dict.fromkeys([column, *where_columns]))):
            v = t[column].to_numpy(zero_copy_only=False)
            values.append(v)
            sizes.append(t.num_rows)
            if where is not None:
                masks.append(_np(where(t)))
                kept.append(v[masks[-1]])
        whole = np.concatenate(values) if values else np.zeros(0)
        top = self.schema.empty_table()
        among = np.flatnonzero(np.concatenate(masks)) if top_where and masks else np.arange(len(whole))
        if len(among):
            v = whole.astype(float)[among]
            rows = among[np.lexsort((among, v if ascending else -v))[:k]]  # by value, then first occurrence
            starts = np.concatenate([[0], np.cumsum(sizes)])
            part = np.searchsorted(starts, rows, side="right") - 1
            needed = sorted(set(part.tolist()))
            import pyarrow as pa

            grouped = pa.concat_tables([t.take(pa.array(rows[part == p] - starts[p]))  # by part, each in rank order
                                        for p, t in zip(needed, self.at(needed))])
            top = grouped.take(pa.array(np.argsort(np.argsort(part, kind="stable"))))  # back in rank order
        return top, whole, (np.concatenate(kept) if kept else np.zeros(0)) if where is not None else None

    def filter(self, where: Callable):
        """All rows where ``where(part)`` as one table (for rows known to be few)."""
        import pyarrow as pa

        kept = [t.filter(pa.array(_np(where(t)))) for t in self]
        return pa.concat_tables(kept) if kept else self.schema.empty_table()


def _np(mask) -> np.ndarray:
    return np.asarray(mask.to_numpy(zero_copy_only=False) if hasattr(mask, "to_numpy") else mask, dtype=bool)


def _top_k(table, column: str, k: int, ascending: bool = False):
    v = table[column].to_numpy(zero_copy_only=False).astype(float)
    order = table["__order"].to_numpy()
    idx = np.lexsort((order, v if ascending else -v))[:k]  # by value, then first occurrence
    return table.take(idx)


def concat_rows(parts: list[dict]) -> dict:
    """Column-wise concatenation of row dicts (in order)."""
    if len(parts) == 1:
        return parts[0]
    return {c: np.concatenate([np.asarray(r[c]) for r in parts]) for c in parts[0]}
