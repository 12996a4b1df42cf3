"""Command line, the commands that read the store: runs (rm, gc), summarize, plot, export, diff, check.

Registered on ``surgopt.cli_common.app`` when ``surgopt.cli`` is imported; the options, error handling and
tables are ``surgopt.cli_common``'s. One module past 600 lines: each command here is a thin Typer signature over
``results``, ``export`` and ``html_report``, and they share the store's reading helpers (the page writer, the
headline text, the compare table's cells); split by command they would import each other's.
"""
from __future__ import annotations

import sys
from pathlib import Path
from typing import Annotated, Optional

import typer

from surgopt.cli_common import (
    ExportFormat,
    FigureFormat,
    JobsOpt,
    QuietOpt,
    StoreOpt,
    SummaryFormat,
    app,
    wide_console,
    fail,
    guard,
    emit_tables,
    print_table,
)

runs_app = typer.Typer(help="List and delete stored runs.", no_args_is_help=False)
app.add_typer(runs_app, name="runs")


@runs_app.callback(invoke_without_command=True)
def runs(
    ctx: typer.Context,
    store: StoreOpt = None,
    study: Annotated[Optional[str], typer.Option("--study", help="Only this study.")] = None,
    fmt: Annotated[SummaryFormat, typer.Option("--format", help="table, csv, json (every run's manifest facts, "
                                                                 "snake_case keys) or markdown.")] = SummaryFormat.table,
    compare: Annotated[bool, typer.Option("--compare", metavar="", help="The complete runs of --study side by side: the config "
                                                            "values that differ between them and the study's headline "
                                                            "metrics (as dvc exp show).")] = False,
) -> None:
    """List the runs held in the store: study, key prefix, config (with its overrides), rows, state, created.

    State is complete, partial N/M, DAMAGED (a part fails its check; the study command repairs it) or
    UNREADABLE (its manifest), and says which process is writing a run now."""
    if ctx.invoked_subcommand is not None:
        return
    import json

    from rich.table import Table

    with guard(stores=False):
        from surgopt.results import run_records
        from surgopt.store import Store
        from surgopt.studies import STUDIES

        if study is not None and study not in STUDIES:
            fail(f"--study: unknown study {study!r} (one of {', '.join(STUDIES)})", 2)
        s = Store(store)
        if compare:
            _compare(s, study, fmt)
            return
        records = run_records(s, study)
    if fmt == SummaryFormat.json:
        typer.echo(json.dumps(records, indent=1))
        return
    if not records:
        typer.echo(f"no runs in {s.root}", err=fmt != SummaryFormat.table)
        return
    header = ["study", "key", "name, tags", "config", "plan", "rows", "state", "created"]
    rows = []
    for r in records:
        label = " ".join([r.get("name") or ""] + [f"{k}={v}" for k, v in (r.get("tags") or {}).items()]).strip()
        rows.append([r["study"], r["key"][:12], label, r["config_name"] or "?", r.get("plan") or "?",
                     str(r["rows"] if r["rows"] is not None else "?"), r["state"], r.get("created") or "?"])
    if fmt != SummaryFormat.table:
        emit_tables(fmt.value, [(f"runs in {s.root}", header, rows)])
        return
    t = Table(title=f"runs in {s.root}")
    for col in header:
        t.add_column(col, overflow="fold")
    for row in rows:
        t.add_row(*row)
    wide_console(170).print(t)


def _compare(s, study: str | None, fmt) -> None:
    """``runs --compare``: one row per complete run of the study, varying config values and headline metrics."""
    import json

    from surgopt.results import compare_records
    from surgopt.studies import get_study

    if study is None:
        fail("--compare needs --study (the runs of one study are compared)", 2)
    varying, metrics, records = compare_records(s, get_study(study))
    if fmt == SummaryFormat.json:
        typer.echo(json.dumps([{"key": r["key"], "name": r["name"], "plan": r["plan"],
                                "params": {k: r["config"].get(k) for k in varying},
                                "metrics": {k: r["headline"][k] for k in metrics}} for r in records], indent=1,
                              default=str))
        return
    if not records:
        typer.echo(f"no complete {study} runs in {s.root}", err=fmt != SummaryFormat.table)
        return
    # the headline first, then the config values that differ (a narrow terminal keeps the columns from the left:
    # best_cost and feasible, not a landmark's coordinates; issue 56 item 8); paths by their file name and hashes
    # by their first 12 digits (item 10; --format json keeps them whole)
    rows = [[r["key"][:12], r["name"], r["plan"]]
            + [f"{r['headline'][k]:.6g}" if isinstance(r["headline"][k], float) else str(r["headline"][k])
               for k in metrics] + [_short(r["config"].get(k)) for k in varying] for r in records]
    emit_tables(fmt.value, [(f"{study} runs in {s.root}: the headline, and the config values that differ",
                             ["key", "name", "plan"] + metrics + varying, rows)])


def _short(value) -> str:
    """A config value as ``runs --compare`` shows it: a path by its file name, a sha256 by its first 12 hex
    digits, anything else as JSON."""
    import json
    import re

    if isinstance(value, str) and re.fullmatch(r"[0-9a-f]{64}", value):
        return value[:12]
    if isinstance(value, str) and value.startswith("/") and "/" in value[1:]:
        return value.rsplit("/", 1)[1]
    return json.dumps(value, default=str)


@runs_app.command("rm")
def runs_rm(
    keys: Annotated[list[str], typer.Argument(help="Key prefixes of the runs (see `surgopt runs`).")],
    store: StoreOpt = None,
    dry_run: Annotated[bool, typer.Option("--dry-run", metavar="", help="Say what would be removed; remove "
                                                                        "nothing.")] = False,
) -> None:
    """Delete stored runs (only ever inside the store root; refused while a study is writing one). Every key
    must match exactly one run, or nothing is removed."""
    import shutil

    with guard():
        from surgopt.store import Store, folder_study_key

        s = Store(store)
        found = []
        for key in keys:
            if len(key) < 4 or any(c not in "0123456789abcdef" for c in key):
                fail(f"{key!r}: give at least 4 hex digits of a key (see `surgopt runs`)", 2)
            matches = [r for r in s.runs() if r.key.startswith(key)]
            broken = [p for p, _ in s.unreadable() if folder_study_key(p)[1].startswith(key)]
            if len(matches) + len(broken) != 1:
                fail(f"{key}: matches {len(matches) + len(broken)} runs in {s.root}; nothing was removed", 2)
            found.append(matches[0] if matches else broken[0])
        for item in found:
            if isinstance(item, Path):
                study_name, folder_key = folder_study_key(item)
                if dry_run:
                    typer.echo(f"would remove {study_name} {folder_key[:12]} (its manifest is unreadable)")
                    continue
                shutil.rmtree(item)
                typer.echo(f"removed {study_name} {folder_key[:12]} (its manifest was unreadable)")
                continue
            if dry_run:
                typer.echo(f"would remove {item.study} {item.key[:12]} ({item.rows:,} rows, {item.path})")
                continue
            s.remove(item)
            typer.echo(f"removed {item.study} {item.key[:12]}")


@runs_app.command("gc")
def runs_gc(store: StoreOpt = None) -> None:
    """Delete partial (interrupted) runs, stray part and temporary files left by killed writers, and
    abandoned --force rebuilds. Runs that a study is writing now (their lock is held) are left alone."""
    with guard():
        from surgopt.store import Store

        s = Store(store)
        removed = s.gc()
    typer.echo(f"removed {len(removed)} item(s)" + "".join(f"\n  {p}" for p in removed))


RunRef = Annotated[Optional[str], typer.Argument(
    help="A key prefix from `surgopt runs`, a run's --name, `latest`, or the config that produced the run. Default: "
         "the latest run.",
    show_default=False)]
StudyOpt = Annotated[Optional[str], typer.Option("--study", help="Study name, when a config fits several.")]


def _shortest(x) -> str:
    """A float as the shortest text that reads back to the same float (repr)."""
    return repr(float(x))


@app.command("summarize")
def summarize(
    run: RunRef = None,
    store: StoreOpt = None,
    study: StudyOpt = None,
    fmt: Annotated[SummaryFormat, typer.Option("--format", help="table, csv, json (stable snake_case keys, full "
                                                                 "precision) or markdown.")] = SummaryFormat.table,
    top: Annotated[int, typer.Option("--top", min=1, help="How many designs to list.")] = 10,
    sort: Annotated[Optional[str], typer.Option("--sort", help="Column to rank by, largest first; -COLUMN ranks the "
                                                               "smallest first (default: the study's objective).",
                                                show_default=False)] = None,
    columns: Annotated[Optional[str], typer.Option("--columns", help="Comma-separated columns of the top table "
                                                                     "(default: every number column).",
                                                   show_default=False)] = None,
) -> None:
    """Summary of a stored run: top designs by the study's objective, its distribution, feasibility,
    and for studies without an objective their own comparison tables. Works on partial runs and says so."""
    fmt = fmt.value
    with guard(stores=False):
        from surgopt.report import render, run_sections
        from surgopt.results import resolve_run
        from surgopt.store import Store

        st, r = resolve_run(Store(store), run, study)
        if fmt == "json":
            import json

            from surgopt.report import run_record

            typer.echo(json.dumps(run_record(st, r, top=top, sort=sort), indent=1, default=str))
            return
        if fmt == "csv":  # one table pandas.read_csv reads as it is: the top rows, every column, full precision
            from surgopt.report import top_table

            table = top_table(st, r.parts(st.schema_for(r.manifest["config"])), top=top, sort=sort)
            if table is None:
                fail(f"--format csv writes the top rows by a column: {st.name} ranks nothing by default, so give "
                      f"--sort COLUMN (or use --format json / markdown for its comparison tables)", 2)
            if columns:
                table = table.select([c.strip() for c in columns.split(",") if c.strip()])
            sys.stdout.write(table.to_pandas().to_csv(index=False, float_format=_shortest))
            return
        shown = [c.strip() for c in columns.split(",") if c.strip()] if columns else None
        sections = run_sections(st, r, top=top, sort=sort, columns_shown=shown)
    if fmt != "table":
        typer.echo(render(sections, fmt))
        return
    console = wide_console(0)  # the terminal's width; cells fold rather than being cut
    for title, header, rows in sections:
        print_table(console, title, header, rows)


#: A run's figures in its own folder: the leading "_" makes pyarrow, pandas and the README's readers skip it.
FIGURES_FOLDER = "_figures"


@app.command("plot")
def plot(
    run: RunRef = None,
    out: Annotated[Optional[Path], typer.Option(
        "--out", help="Folder for the figures \\[default: the run's own folder in the store, "
                      "STORE/study=<study>/key=<key>/_figures, kept with the run as MLflow keeps artifacts; "
                      "Parquet readers skip it]", show_default=False)] = None,
    fmt: Annotated[FigureFormat, typer.Option("--format", help="png, pdf or svg.")] = FigureFormat.png,
    store: StoreOpt = None,
    study: StudyOpt = None,
    design: Annotated[Optional[int], typer.Option(
        "--design", help="The design_id of a study's per-design figure (raven-sweep's common workspace; "
                         "default: the best by the study's objective).",
        show_default=False)] = None,
) -> None:
    """Figures of a stored run in the style of its paper (each study's own; docs/figures shows them
    for the paper setups)."""
    if out is not None and out.exists() and not out.is_dir():
        fail(f"--out: {out} is a file; give a folder for the figures", 2)
    with guard(stores=False):
        if out is not None:  # not into a run folder of the store (leave --out off to write beside the run)
            from surgopt.outputs import checked

            checked(out)
        from surgopt.results import config_of, resolve_run
        from surgopt.store import Store

        st, r = resolve_run(Store(store), run, study)
        cfg = config_of(st, r)
        plan = st.search_plan(cfg) if st.search_plan else None
        only = st.figure_columns(r.manifest["config"]) if st.figure_columns and plan is None else None
        table = r.read_table(st.schema_for(r.manifest["config"]), only)
        if table.num_rows == 0:
            fail(f"{r.key[:12]}: the run has no rows yet", 1)
        id_column = st.key_columns[0]
        if design is not None and design not in set(table[id_column].to_pylist()):
            fail(f"--design: no {id_column} {design} in run {r.key[:12]}", 2)
        out = out if out is not None else r.path / FIGURES_FOLDER
        out.mkdir(parents=True, exist_ok=True)
        from surgopt.studies.plotting import set_format, stamped

        set_format(fmt.value)
        with stamped(run_stamp(st.name, r)):
            if plan is not None:
                from surgopt.studies.plotting import search_figures

                from surgopt.report import feasible_rows

                paths = search_figures(cfg, table, out, plan, reference=_grid_best(Store(store), st, cfg, plan,
                                                                                     st.reported_objective),
                                       feasible=feasible_rows(st, table), objective=st.reported_objective)
            else:
                paths = st.figures(cfg, table, out, design)
        from surgopt.report import best_edges

        notes = best_edges(st, r, r.parts(st.schema_for(r.manifest["config"])))
    which = "" if run is not None else f", the latest{' ' + study if study else ''} run in the store"
    typer.echo(f"drew {st.name} run {r.key[:12]} ({r.manifest.get('name') or r.manifest.get('config_name', '')}"
               f"{which}):", err=True)  # which run: the latest may be another study's, finished a second later
    for p in paths:
        typer.echo(str(p))
    for note in notes:  # what the figures show on an edge of the box (#27 item 2)
        typer.echo(f"note: {note}", err=True)


def run_stamp(study: str, run) -> str:
    """What a figure of a run says of it: the study, the key, the run's name or config, surgopt's version."""
    from surgopt._version import __version__

    label = run.manifest.get("name") or run.manifest.get("config_name", "")
    return f"{study} run {run.key[:12]} ({label}) · surgopt {__version__}"


@app.command("report")
def report(
    runs_: Annotated[Optional[list[str]], typer.Argument(
        metavar="[RUN]...", help="Key prefixes, names or configs of stored runs \\[default: the store's latest run]; "
                                 "several make one comparison page.", show_default=False)] = None,
    out: Annotated[Optional[Path], typer.Option(
        "--out", help="The page's file \\[default: beside the run in the store, STORE/study=<study>/key=<key>/"
                      "_report.html; a comparison or the index: STORE/_report.html]", show_default=False)] = None,
    store_index: Annotated[bool, typer.Option(
        "--store-index", help="One page listing every run of the store (name, tags, headline) with a link to each "
                              "run's page (written too).")] = False,
    store: StoreOpt = None,
    study: StudyOpt = None,
) -> None:
    """One self-contained HTML page of a run to explore in a browser: every script embedded, nothing fetched,
    so it opens offline from a file (a hospital laptop, an e-mail). Each study shows what its paper would:
    port-place the layout in 3-D on the patient, with a table of the top layouts that redraws the scene and the
    clinical checks on a click; rcm-grid the GII map with Table I; raven-sweep the cost landscape; suture-sim the
    joint trajectories; a search its convergence on the objective's own scale. Aggregates only, never millions of
    rows (the page says how to export them)."""
    if out is not None and out.is_dir():
        fail(f"--out: {out} is a folder; give the page's file name (e.g. report.html)", 2)
    with guard(stores=False):
        if out is not None and str(out) != "-":  # not into the store's own files (its run folders, parts, ...)
            from surgopt.outputs import checked

            checked(out)
        from surgopt import html_report as H
        from surgopt.results import resolve_run, run_records
        from surgopt.store import Store

        s = Store(store)
        if store_index:
            import os

            path = out or s.root / H.REPORT_FILE
            records = [rec for rec in run_records(s, study) if not str(rec["state"]).startswith("UNREADABLE")]
            written, kept = [], []
            for i, rec in enumerate(records):
                st, r = resolve_run(s, rec["key"], rec["study"])
                if r.manifest["parts"]:
                    page = r.path / H.REPORT_FILE
                    if H.current_page(r, page):  # built from this run as it is, by this code: kept
                        kept.append(page)
                    else:
                        typer.echo(f"page {i + 1} of {len(records)}: {st.name} run {r.key[:12]} ...", err=True)
                        written.append(_write_page(H, st, r, page))
                    rec["link"] = os.path.relpath(page, path.resolve().parent)
                rec["headline"] = _headline_text(s, rec)
            _write_text(path, H.index_page(s, records))
            typer.echo(f"{path} (the store's {len(records)} runs; {len(written)} run pages written beside them, "
                       f"{len(kept)} kept: current)")
            return
        refs = runs_ or [None]
        items = []
        for ref in refs:
            st, r = resolve_run(s, ref, study)
            items.append((st, r, r.parts(st.schema_for(r.manifest["config"]))))
        if len(items) == 1:
            st, r, _ = items[0]
            from surgopt.results import study_of_config

            ref = refs[0]  # a config names the run: what it adds beyond the run's key (a given layout) is shown too
            given = study_of_config(Path(ref), study)[1] if ref is not None and Path(ref).is_file() else None
            path = _write_page(H, st, r, out or r.path / H.REPORT_FILE,
                               "--out" if out else "the page beside the run (--out FILE writes it elsewhere)", given)
            latest = "" if runs_ else f" (the latest {study + ' ' if study else ''}run in the store)"
            typer.echo(f"{path}: {st.name} run {r.key[:12]} {r.manifest.get('config_name', '')}{latest}",
                       err=str(path) == "-")  # the page itself on standard output: the word beside it
            return
        path = out or s.root / H.REPORT_FILE
        _write_text(path, H.comparison_page(items))
        typer.echo(f"{path}: {len(items)} runs compared ({', '.join(r.key[:8] for _, r, _ in items)})")


def _write_page(H, st, r, path: Path, option: str = "the page beside the run (--out FILE writes it elsewhere)",
                given=None) -> Path:
    from surgopt.cli_common import announced

    with announced(f"building the page of {st.name} run {r.key[:12]} ({r.rows:,} rows)"):
        text = H.run_page(st, r, r.parts(st.schema_for(r.manifest["config"])), given)
    _write_text(path, text, option)
    return path


def _write_text(path: Path, text: str, option: str = "--out") -> None:
    """Atomically (a reader never sees half a page), through what is not a regular file (a FIFO, /dev/stdout),
    ``-``: standard output (``outputs.write_text_out``); the caller has refused a user's path into the store, and
    the page beside a run is the command's own."""
    from surgopt.outputs import write_text_out

    write_text_out(path, text, option, own=True)


def _headline_text(s, rec) -> str:
    """A run's headline numbers in one line (as its manifest keeps them, else from its summary; empty for a run
    with no rows or not complete)."""
    from surgopt.results import headline_of, resolve_run

    try:
        st, r = resolve_run(s, rec["key"], rec["study"])
        if not r.complete:
            return ""
        head = headline_of(s, st, r)
    except Exception:  # noqa: BLE001 - a damaged run: the index lists it, its state says why
        return ""
    return "; ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in list(head.items())[:5])


@app.command("export")
def export(
    runs_: Annotated[list[str], typer.Argument(metavar="RUN...", help="Key prefixes (or configs) of the runs to "
                                                                      "export; several runs are stacked.")],
    fmt: Annotated[str, typer.Option("--format", help="csv, parquet or json (records); or a study's own format "
                                                       "of one design (--design), such as port-place's dvrk (the "
                                                       "layout's set-up for the robot: cart pose, setup joints, "
                                                       "ports, as JSON), dvrk-suj-fixed (the dVRK's own SUJ_Fixed "
                                                       "file: each arm's base frame in the cart's) and ports (its "
                                                       "ports and the patient's "
                                                       "landmarks as CSV, each measured from the reference "
                                                       "landmark).")] = "csv",
    design: Annotated[Optional[int], typer.Option("--design", help="The design (its key column's value, e.g. a "
                                                                   "design_id) a study's own format writes.",
                                                  show_default=False)] = None,
    out: Annotated[Optional[Path], typer.Option("--out", help="Output file \\[default: standard output; "
                                                              "needed for parquet].", show_default=False)] = None,
    store: StoreOpt = None,
    study: StudyOpt = None,
    partial: Annotated[bool, typer.Option("--partial", metavar="", help="Export a partial run's stored rows (an interrupted "
                                                            "run, or one being written); without it such a run "
                                                            "is refused.")] = False,
) -> None:
    """A run's whole table as one tidy table, with the run key (and, for several runs, the config fields
    that differ between them) as columns. The CSV reads back with pandas.read_csv as it is."""
    with guard(stores=False):
        from surgopt.results import export_design
        from surgopt.store import Store

        if fmt not in (f.value for f in ExportFormat):
            if design is None or len(runs_) != 1:
                fail(f"--format {fmt}: a study's own format writes one design of one run: give one RUN and --design",
                     2)
            text, notes = export_design(Store(store), runs_[0], design, fmt, study)
            for note in notes:
                typer.echo(note, err=True)
            from surgopt.outputs import is_stdout, write_text_out

            write_text_out(out, text)
            if not is_stdout(out):
                typer.echo(f"wrote {out} (design {design}, {fmt})", err=True)
            return
        if design is not None:
            fail("--design goes with a study's own --format (csv, parquet and json export every row)", 2)
        from surgopt.outputs import checked, is_stdout

        if fmt == ExportFormat.parquet and is_stdout(out):
            fail("--format parquet needs --out FILE", 2)
        if not is_stdout(out):
            checked(out)  # not into the store's own files: refused before anything is read or written
        if out is not None and out.is_dir():
            fail(f"--out: {out} is a folder; give a file", 2)
        from surgopt.export import export_runs, write_csv, write_json, write_parquet

        export = export_runs(Store(store), runs_, study, allow_partial=partial)
        for note in export.notes:
            typer.echo(note, err=True)
        writer = {ExportFormat.csv: write_csv, ExportFormat.parquet: write_parquet, ExportFormat.json: write_json}
        writer[ExportFormat(fmt)](export, out, lambda m: typer.echo(m, err=True))
    if out is not None and str(out) != "-":
        size = out.stat().st_size if out.is_file() else None
        typer.echo(f"wrote {out} ({export.num_rows} rows, {len(export.schema)} columns"
                   f"{'' if size is None else f', {size / 1e6:,.1f} MB'})", err=True)


@app.command("diff")
def diff(
    run_a: Annotated[str, typer.Argument(help="Key prefix (or config) of the first run.")],
    run_b: Annotated[str, typer.Argument(help="Key prefix (or config) of the second run.")],
    fmt: Annotated[SummaryFormat, typer.Option("--format", help="table, csv (each table under a '# title' line), "
                                                                 "json or markdown.")] = SummaryFormat.table,
    store: StoreOpt = None,
    study: StudyOpt = None,
    top: Annotated[int, typer.Option("--top", min=1, help="How many of the most changed rows to list.")] = 5,
) -> None:
    """Compare two runs of one study: the config fields that differ, then every metric joined on the
    study's key columns (rows only in one run, largest changes, the best design of each)."""
    import json

    with guard(stores=False):
        from surgopt.results import diff_runs
        from surgopt.store import Store

        d = diff_runs(Store(store), run_a, run_b, study, top)
    if fmt == SummaryFormat.json:
        typer.echo(json.dumps(d, indent=1, default=str))
        return
    out = [(f"config: {d['a']['key'][:12]} vs {d['b']['key'][:12]}", ["field", "a", "b"],
            [[k, str(a), str(b)] for k, (a, b) in d["config"].items()] or [["(identical configs)", "", ""]])]
    if d["rows_joined"]:
        out.append((f"metrics over {d['rows_joined']} rows joined on {', '.join(d['key_columns'])} "
                    f"({d['rows_only_a']} only in a, {d['rows_only_b']} only in b)",
                    ["column", "rows changed", "max |b - a|", "mean b - a"],
                    [[c, m["changed"], f"{m['max_abs']:.6g}", f"{m['mean']:.6g}"] for c, m in d["metrics"].items()]))
    else:  # issue 56 item 9: 29 rows of zeros said nothing
        out.append(f"no layout in common: no row of a ({d['rows_only_a']:,}) has the {', '.join(d['key_columns'])} "
                   f"of a row of b ({d['rows_only_b']:,})"
                   + ("; the best of each is compared below" if d["best"] and (d["best"]["a"] or d["best"]["b"])
                      else ""))
    if d["worst"]:
        cols = list(d["worst"][0])
        out.append((f"most changed rows (by |b - a| of {d['objective']})", cols,
                    [[_cell(r[c]) for c in cols] for r in d["worst"]]))
    if d["best"] is not None and d["best"] and not (d["best"]["a"] or d["best"]["b"]):
        out.append(f"neither run has a {'feasible ' if d.get('best_among') == 'feasible' else ''}design to compare "
                   f"by {d['objective']}")
    if d["best"] and (d["best"]["a"] or d["best"]["b"]):
        header = list(d["best"]["a"] or d["best"]["b"])
        out.append((f"best design of each by {d['objective']}" + (" (feasible, least first)" if
                    d.get("best_among") == "feasible" else ""), ["run", *header],
                    [[run, *(_cell(d["best"][run][c]) if d["best"][run] else "-" for c in header)] for run in "ab"]))
    emit_tables(fmt.value, out)


def _cell(v) -> str:
    """A value as a table shows it: floats to 6 significant digits (the JSON format keeps full precision), so a
    number is never folded across lines."""
    return f"{v:.6g}" if isinstance(v, float) else str(v)


@app.command("check")
def check(
    config: Annotated[Path, typer.Argument(help="Config of the study to run (or reuse from the store).")],
    baseline: Annotated[Path, typer.Option("--baseline", help="Parquet baseline to compare with.")],
    overrides: Annotated[Optional[list[str]], typer.Argument(
        help="KEY=VALUE overrides on the config, as for the study commands.", metavar="[KEY=VALUE]...",
        show_default=False)] = None,
    rtol: Annotated[float, typer.Option("--rtol", min=0, help="Relative tolerance on float columns.")] = 1e-9,
    atol: Annotated[float, typer.Option("--atol", min=0, help="Absolute tolerance on float columns.")] = 1e-12,
    write: Annotated[bool, typer.Option("--write", metavar="", help="(Re)create the baseline from this run instead.")] = False,
    store: StoreOpt = None,
    study: StudyOpt = None,
    jobs: JobsOpt = 2,
    quiet: QuietOpt = True,
) -> None:
    """Run (or reuse) a study and compare it with a stored Parquet baseline: key columns exactly, float
    columns within rtol/atol, after sorting by the key. Exit 0 within tolerance, 1 when not, 2 on bad input."""
    with guard():
        import pyarrow.parquet as pq

        from surgopt.results import compare_tables, study_of_config, write_baseline
        from surgopt.runner import run_study
        from surgopt.store import Store

        st, cfg = study_of_config(config, study)
        name = config.stem
        if overrides:
            from surgopt.compose import variants

            bad = [o for o in overrides if "=" not in o]
            if bad:
                fail(f"{bad[0]!r}: after CONFIG only KEY=VALUE overrides are allowed", 2)
            (v,) = variants(st, config, overrides)
            cfg, name = v.config, f"{config.stem}{v.config_name[v.config_name.index('+'):]}"
        if not write and not baseline.is_file():
            fail(f"{baseline}: baseline not found (create it with --write)", 2)
        res = run_study(st, cfg, config_name=name, store=Store(store), jobs=jobs, quiet=quiet,
                        say=lambda m: typer.echo(m, err=True))
        if write:
            write_baseline(res.table, st.key_columns, baseline)
            typer.echo(f"wrote {baseline} ({res.table.num_rows} rows)")
            return
        try:
            base = pq.read_table(baseline)
        except Exception as exc:  # noqa: BLE001 - any unreadable file is bad input
            fail(f"{baseline}: not a readable Parquet file ({exc})", 2)
        current = res.table
        problems, diffs = compare_tables(current, base, st.key_columns, rtol, atol)
    for p in problems:
        typer.echo(f"FAIL: {p}")
    if diffs:
        typer.echo(f"FAIL: {len(diffs)} value(s) differ beyond rtol={rtol:g}, atol={atol:g}; worst:")
        for d in diffs[:8]:
            typer.echo(f"  {d.column} at {dict(zip(st.key_columns, d.key))}: baseline {d.baseline!r}, now "
                       f"{d.current!r} (relative {d.rel:.3g})")
    if problems or diffs:
        raise typer.Exit(1)
    typer.echo(f"OK: {current.num_rows} rows match {baseline} (rtol={rtol:g}, atol={atol:g})")


def _grid_best(store, study, cfg, plan, objective=None):
    """(label, value) of the search's objective over the same config's grid, if stored (``results.grid_best``);
    ``objective`` (column, direction): that column over the grid's feasible designs."""
    from surgopt.results import grid_best

    if len(plan.objectives) != 1:
        return None
    col, direction = objective or plan.objectives[0]
    return grid_best(store, study, cfg, col, direction, feasible_only=objective is not None)
