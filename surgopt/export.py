"""Whole runs written out as one tidy table (``surgopt export``): CSV, Parquet or JSON records, part by part.

Orchestration only: the runs are read through their ``Study`` declaration. The rows stream from the
stored Parquet parts to the output one part at a time (issue 42 item 5: a 2.2 M-row port-place run
held whole in pandas and formatted value by value took 108 s and 4.6 GB; part by part through
Arrow's CSV writer it is a few seconds and one part's memory).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Iterator

from surgopt.errors import UsageError
from surgopt.results import flat_config, require_complete, resolve_run
from surgopt.store import Store


@dataclass(frozen=True)
class Export:
    """Several runs' rows as one table: its ``schema`` (leading ``run_key`` and the config fields that differ
    between the runs, dotted), ``tables()`` yielding it part by part in that schema, ``num_rows``, and ``notes``
    to print (what a reader of the stacked table must know)."""

    schema: object
    tables: Callable[[], Iterator]
    num_rows: int
    notes: tuple[str, ...]


def export_runs(store: Store, refs: list[str], study_name: str | None = None, allow_partial: bool = False) -> Export:
    """The runs ``refs`` stacked (one study; a partial run refused unless ``allow_partial``)."""
    import pyarrow as pa

    resolved = [resolve_run(store, ref, study_name) for ref in refs]
    for _, r in resolved:
        require_complete(store, r, allow_partial)
    studies = {st.name for st, _ in resolved}
    if len(studies) > 1:
        raise UsageError(f"the runs are of different studies ({', '.join(sorted(studies))}); export them one by one")
    flats = [flat_config(r.manifest["config"]) for _, r in resolved]
    varied = [k for k in flats[0] if len({repr(f.get(k)) for f in flats}) > 1] if len(flats) > 1 else []
    leading = [{"run_key": pa.scalar(r.key, pa.string()), **{k: _constant(f.get(k)) for k in varied}}
               for (_, r), f in zip(resolved, flats)]
    schemas = [pa.schema([pa.field(k, v.type) for k, v in lead.items()] + list(st.schema_for(r.manifest["config"])))
               for (st, r), lead in zip(resolved, leading)]
    schema = pa.unify_schemas(schemas, promote_options="permissive")

    def tables():
        for (st, r), lead in zip(resolved, leading):
            for t in r.parts(st.schema_for(r.manifest["config"])):
                yield _conform(t, lead, schema)

    return Export(schema, tables, sum(r.rows for _, r in resolved), _identity_notes(resolved))


def _constant(value):
    """A config value as one Arrow scalar for a constant column (lists and tables as their text)."""
    import pyarrow as pa

    return pa.scalar(value if isinstance(value, (int, float, str, bool)) or value is None else str(value))


def _conform(table, lead: dict, schema):
    """``table`` with the constant columns ``lead`` in front, in ``schema``'s column order and types (a column
    another run has and this one lacks: nulls)."""
    import pyarrow as pa

    n = table.num_rows
    columns = []
    for field in schema:
        if field.name in lead:
            col = pa.repeat(lead[field.name].cast(field.type), n)
        elif field.name in table.column_names:
            col = table[field.name].cast(field.type)
        else:
            col = pa.nulls(n, field.type)
        columns.append(col)
    return pa.Table.from_arrays(columns, schema=schema)


def _identity_notes(resolved) -> tuple[str, ...]:
    """For several runs of a study whose designs are numbered per run (port-place's design_id and site indices
    count each run's own candidate sites): which columns identify a design across the runs (issue 42 item 1)."""
    if len(resolved) < 2:
        return ()
    st, r = resolved[0]
    if st.design_identity is None:
        return ()
    keys, index_only = st.design_identity(r.manifest["config"])
    return (f"note: {', '.join(index_only)} number each run's own designs; the same design in two runs has the "
            f"same {', '.join(keys)} (match on those, rounded to 1e-6)",)


#: An export says how far it is once it has taken this long, then every PROGRESS_EVERY_S (issue 56 item 5: a
#: 2.4 M-row CSV export, 1.33 GB, ran a minute with no word).
PROGRESS_AFTER_S = 2.0
PROGRESS_EVERY_S = 5.0


class Progress:
    """Rows and bytes an export has written, said on ``say`` once it runs past PROGRESS_AFTER_S, then every
    PROGRESS_EVERY_S ("export: 1,200,000 of 2,400,000 rows (50 %), 650 MB written"); silent without ``say``."""

    def __init__(self, total_rows: int, say: Callable[[str], None] | None = None, clock=None):
        import time

        self.total, self.say, self.clock = total_rows, say, clock or time.monotonic
        self.rows = self.bytes = 0
        self.next_s = self.clock() + PROGRESS_AFTER_S
        self.said = 0

    def add(self, rows: int = 0, nbytes: int = 0) -> None:
        self.rows += rows
        self.bytes += nbytes
        if self.say is not None and self.clock() >= self.next_s:
            share = f" ({100 * self.rows / self.total:.0f} %)" if self.total else ""
            written = f", {self.bytes / 1e6:,.0f} MB written" if self.bytes else ""
            self.say(f"export: {self.rows:,} of {self.total:,} rows{share}{written} ...")
            self.said += 1
            self.next_s = self.clock() + PROGRESS_EVERY_S


def write_csv(export: Export, out: Path | None, say: Callable[[str], None] | None = None) -> None:
    """The rows as CSV (a header line, then each part's lines; see ``csv_lines``), to ``out`` atomically or to
    standard output. ``pandas.read_csv`` reads it back as it is. ``say``: where its progress goes (``Progress``)."""
    progress = Progress(export.num_rows, say)

    def write(sink) -> None:
        sink.write((",".join(_csv_text(f.name) for f in export.schema) + "\n").encode())
        for rows, lines in _in_order(lambda t: (t.num_rows, csv_lines(t)), export.tables()):
            sink.write(lines)
            progress.add(rows, len(lines))

    _to(out, write)


def _in_order(f: Callable, items, workers: int = 2) -> Iterator:
    """``f`` of each item, in order, computed on ``workers`` threads (Arrow's kernels release the GIL) with at
    most two items per worker ahead of the one being consumed (memory: a few parts)."""
    from collections import deque
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(workers) as pool:
        pending = deque()
        for item in items:
            pending.append(pool.submit(f, item))
            if len(pending) > 2 * workers:
                yield pending.popleft().result()
        while pending:
            yield pending.popleft().result()


def write_parquet(export: Export, out: Path, say: Callable[[str], None] | None = None) -> None:
    """The rows as one Parquet file (zstd), written part by part, atomically (``say``: its progress)."""
    import pyarrow.parquet as pq

    progress = Progress(export.num_rows, say)

    def write(sink) -> None:
        with pq.ParquetWriter(sink, export.schema, compression="zstd") as w:
            for t in export.tables():
                w.write_table(t)
                progress.add(t.num_rows)

    _to(out, write)


def write_json(export: Export, out: Path | None, say: Callable[[str], None] | None = None) -> None:
    """The rows as JSON records (the whole table in memory: meant for small runs; ``say`` unused, as one step)."""
    import pyarrow as pa

    tables = list(export.tables())
    df = (pa.concat_tables(tables) if tables else export.schema.empty_table()).to_pandas()
    text = df.to_json(orient="records", indent=1).encode()
    _to(out, lambda sink: sink.write(text))


def _to(out: Path | None, write: Callable) -> None:
    """``outputs.write_out``: standard output (None or ``-``), through what is not a regular file, else atomically;
    never into the store's own files."""
    from surgopt.outputs import write_out

    write_out(out, write)


def csv_lines(table) -> bytes:
    """One part as CSV lines, every column turned to text by Arrow and the lines joined there: floats as the
    shortest text that reads back to the same float, with ".0" after an integral one (pandas reads the column
    back as floats, as it was); booleans True/False; NaN and a missing value empty (as pandas writes them); text quoted only where it
    holds a comma, a quote or a line break (pandas' and the csv module's minimal quoting)."""
    import numpy as np
    import pyarrow as pa
    import pyarrow.compute as pc

    if not table.num_rows:
        return b""
    texts = [pc.fill_null(_column_text(table[name].combine_chunks()), "") for name in table.column_names]
    lines = pc.binary_join_element_wise(pc.binary_join_element_wise(*texts, ","), "\n", "")
    width = np.int32 if lines.type == pa.string() else np.int64
    offsets = np.frombuffer(lines.buffers()[1], dtype=width)[lines.offset:lines.offset + len(lines) + 1]
    return memoryview(lines.buffers()[2])[offsets[0]:offsets[-1]]


def _column_text(col):
    """One column as CSV cells (see ``csv_lines``)."""
    import pyarrow as pa
    import pyarrow.compute as pc

    if pa.types.is_dictionary(col.type):
        col = col.cast(col.type.value_type)
    if pa.types.is_floating(col.type):
        col = col.cast(pa.float64())  # a float32's own value, not its shortest float32 text
        text = pc.cast(col, pa.string())
        # a finite integral value Arrow wrote without a point or an exponent (72; not 1e+10, inf): 72.0
        integral = pc.and_(pc.and_(pc.is_finite(col), pc.equal(pc.floor(col), col)),
                           pc.invert(pc.match_substring(text, "e")))
        text = pc.if_else(integral, pc.binary_join_element_wise(text, ".0", ""), text)
        return pc.if_else(pc.is_nan(col), None, text)  # empty, as pandas writes NaN
    if pa.types.is_string(col.type) or pa.types.is_large_string(col.type):
        return _csv_text(col)
    if pa.types.is_boolean(col.type):  # as Python and pandas write them
        return pc.if_else(col, "True", "False")
    return pc.cast(col, pa.string())


def _csv_text(value):
    """Text (one str or an Arrow string array) quoted where it holds a comma, a quote or a line break."""
    if isinstance(value, str):
        return f'"{value.replace(chr(34), chr(34) * 2)}"' if any(c in value for c in ',"\r\n') else value
    import pyarrow.compute as pc

    quoted = pc.binary_join_element_wise('"', pc.replace_substring(value, '"', '""'), '"', "")
    return pc.if_else(pc.match_substring_regex(value, '[,"\r\n]'), quoted, value)
