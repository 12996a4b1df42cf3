"""Command line: thin Typer commands that parse, call the library and render.

Heavy imports (numpy, numba, pyarrow) happen inside the commands so that
``surgopt --help`` stays instant.
"""
from __future__ import annotations

import contextlib
import signal
import sys
from pathlib import Path
from typing import Annotated, Optional

import typer

app = typer.Typer(
    name="surgopt",
    help="Kinematic design studies of surgical robots, batch-run with a cached Parquet result store.\n\n"
    "Each study command runs the paper's own setup when given no CONFIG. Results go to the store "
    "(--store, $SURGOPT_STORE, or ./surgopt-store); an identical config is a cache hit and an "
    "interrupted run resumes where it stopped.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)

StoreOpt = Annotated[Optional[str], typer.Option(
    "--store", envvar="SURGOPT_STORE", help="Result store folder [default: ./surgopt-store].",
    show_default=False)]
JobsOpt = Annotated[int, typer.Option("--jobs", "-j", min=1, max=256,
                                      help="Parallel workers: threads (threads), worker processes (loky), or LocalCluster workers (dask).")]
ForceOpt = Annotated[bool, typer.Option("--force", help="Recompute even if the store holds this study.")]
QuietOpt = Annotated[bool, typer.Option("--quiet", "-q", help="No progress bar.")]
BackendOpt = Annotated[str, typer.Option(
    "--backend", help="threads (a thread pool in this process: the kernels release the GIL, so they run "
                      "in parallel with no worker start-up), loky (local worker processes) or dask (a "
                      "distributed cluster through joblib's dask backend; needs pip install 'surgopt[dask]').")]
SchedulerOpt = Annotated[Optional[str], typer.Option(
    "--scheduler", help="With --backend dask: the scheduler address (tcp://host:8786). Without it, a "
                        "LocalCluster of --jobs single-threaded workers.", show_default=False)]
MaxHoursOpt = Annotated[float, typer.Option(
    "--max-hours", min=0.0, help="Refuse a config whose estimated work exceeds this many hours on --jobs cores "
                                 "(the estimate is printed; raise this to run it anyway).")]
MaxMemoryOpt = Annotated[Optional[float], typer.Option(
    "--max-memory-gb", min=0.0, help="Refuse a config whose estimated peak memory exceeds this "
                                     "[default: half of this machine's memory].", show_default=False)]
ChunkOpt = Annotated[Optional[int], typer.Option(
    "--chunk-size", min=1, help="Design points per task (a resumed run keeps the size it started with).",
    show_default=False)]


def _fail(exc: BaseException, code: int) -> None:
    typer.echo(f"surgopt: error: {exc}", err=True)
    raise typer.Exit(code)


class Stopped(KeyboardInterrupt):
    """SIGTERM or SIGHUP (what cluster schedulers send before SIGKILL), handled like Ctrl-C."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


def _stop_on(signum, _frame):
    raise Stopped(signum)


RESUME = "finished chunks are stored, run the same command again to resume"


@contextlib.contextmanager
def _guard():
    """Every failure a command can meet ends in one line on stderr and an exit code: 2 bad input,
    1 a failed run or store, 130 / 143 / 129 interrupted by SIGINT / SIGTERM / SIGHUP."""
    from surgopt.errors import SurgoptError

    try:
        yield
    except SurgoptError as exc:
        _fail(exc, exc.exit_code)
    except Stopped as exc:
        typer.echo(f"surgopt: stopped by {signal.Signals(exc.signum).name}; {RESUME}", err=True)
        raise typer.Exit(128 + exc.signum)
    except KeyboardInterrupt:
        typer.echo(f"surgopt: interrupted; {RESUME}", err=True)
        raise typer.Exit(130)
    except MemoryError:
        _fail(f"out of memory; {RESUME} (a smaller config, or --jobs 1)", 1)
    except OSError as exc:
        from surgopt.store import is_disk_full

        where = f" writing {exc.filename}" if exc.filename else ""
        if is_disk_full(exc):
            _fail(f"the disk is full{where}; {RESUME} once there is space", 1)
        _fail(f"{exc.strerror or exc}{where}", 1)


def _load_study_config(study, config: Optional[Path]):
    from surgopt.config import load_config, load_embedded

    if config is None:
        return load_embedded(study.default_config, study.config_model), f"embedded:{Path(study.default_config).stem}"
    return load_config(config, study.config_model), config.stem


def _study_command(study) -> None:
    """Register ``surgopt <study.name>``: its CONFIG argument, its own flags, and the shared options.

    The command's signature is built from the study's declaration (``Study.flags``, ``Study.chunked``),
    so this module names no study.
    """
    import inspect

    P = inspect.Parameter
    params = [P("config", P.KEYWORD_ONLY, default=None, annotation=Annotated[Optional[Path], typer.Argument(
        help=study.config_help, show_default=False)])]
    params += [P(f.dest, P.KEYWORD_ONLY, default=False, annotation=Annotated[bool, typer.Option(f.option, help=f.help)])
               for f in study.flags]
    shared = [("store", StoreOpt, None), ("jobs", JobsOpt, 2), ("force", ForceOpt, False), ("quiet", QuietOpt, False)]
    if study.chunked:
        shared.append(("chunk_size", ChunkOpt, None))
    shared += [("backend", BackendOpt, "threads"), ("scheduler", SchedulerOpt, None),
               ("max_hours", MaxHoursOpt, 1.0), ("max_memory_gb", MaxMemoryOpt, None)]
    params += [P(name, P.KEYWORD_ONLY, default=default, annotation=ann) for name, ann, default in shared]

    def command(**kw) -> None:
        flags = [f for f in study.flags if kw.pop(f.dest)]
        _run_study_command(study, flags=flags, **kw)

    command.__signature__ = inspect.Signature(params)
    command.__annotations__ = {p.name: p.annotation for p in params}
    command.__doc__ = study.help
    command.__name__ = study.name.replace("-", "_")
    app.command(study.name)(command)


def _run_study_command(study, config, store, jobs, force, quiet, chunk_size=None, backend="threads", scheduler=None,
                       max_hours=1.0, max_memory_gb=None, flags=()):
    with _guard():
        from surgopt.runner import run_study
        from surgopt.store import Store

        cfg, config_name = _load_study_config(study, config)
        updates = {k: v for f in flags if f.config_update for k, v in f.config_update.items()}
        if updates:
            cfg = study.config_model.model_validate({**cfg.model_dump(), **updates})
        say = lambda m: typer.echo(m, err=True)  # noqa: E731
        budget = dict(max_hours=max_hours, max_memory_bytes=None if max_memory_gb is None else int(max_memory_gb * 2 ** 30))
        result = run_study(study, cfg, config_name=config_name, store=Store(store), jobs=jobs,
                           force=force, quiet=quiet, chunk=chunk_size, backend=backend, scheduler=scheduler,
                           say=say, **budget)
        _report(study, result)
        for f in flags:
            if f.follow_up is None:
                continue
            follow = run_study(study, f.follow_up(cfg, result.parts), config_name=config_name + f.follow_up_suffix,
                               store=Store(store), jobs=jobs, force=force, quiet=quiet, backend=backend,
                               scheduler=scheduler, say=say, **budget)
            _report(study, follow)


def _register_studies() -> None:
    from surgopt.studies import STUDIES, get_study

    for name in STUDIES:
        _study_command(get_study(name))


_register_studies()


def _console(min_width: int = 150):
    from rich.console import Console

    return Console(width=max(Console().width, min_width))  # wide tables stay readable when piped


def _print_table(console, title, header, rows) -> None:
    from rich.table import Table

    t = Table(title=title)
    for h in header:
        t.add_column(str(h), justify="left" if h == header[0] else "right")
    for row in rows:
        t.add_row(*[str(v) for v in row])
    console.print(t)


def _report(study, result) -> None:
    from rich.table import Table

    console = _console()
    for m in result.messages:
        console.print(m)
    run = result.run
    if result.cache_hit:
        console.print(f"cache hit: {study.name} {run.key[:12]} already in {run.path}")
    summary = study.summary(result.parts)
    t = Table(title=f"{study.name} ({run.manifest['config_name']})", show_header=False)
    for k, v in summary.headline.items():
        t.add_row(k, f"{v:.6g}" if isinstance(v, float) else str(v))
    t.add_row("rows", str(result.parts.num_rows))
    t.add_row("time_s", f"{result.elapsed_s:.2f}")
    t.add_row("store", f"{run.path}")
    console.print(t)
    for title, header, rows in summary.tables:
        _print_table(console, title, header, rows)


runs_app = typer.Typer(help="List and delete stored runs.", no_args_is_help=False)
app.add_typer(runs_app, name="runs")


@runs_app.callback(invoke_without_command=True)
def runs(
    ctx: typer.Context,
    store: StoreOpt = None,
    study: Annotated[Optional[str], typer.Option("--study", help="Only this study.")] = None,
) -> None:
    """List the studies held in the store: study, key prefix, config, rows, state, created."""
    if ctx.invoked_subcommand is not None:
        return
    from rich.console import Console
    from rich.table import Table

    with _guard():
        from surgopt.store import Store
        from surgopt.studies import STUDIES

        if study is not None and study not in STUDIES:
            _fail(f"--study: unknown study {study!r} (one of {', '.join(STUDIES)})", 2)
        s = Store(store)
        items = s.runs(study)
        broken = s.unreadable(study)
    if not items and not broken:
        typer.echo(f"no runs in {s.root}")
        return
    t = Table(title=f"runs in {s.root}")
    for col in ("study", "key", "config", "rows", "state", "created"):
        t.add_column(col)
    for r in items:
        damaged = r.damaged()
        if damaged:
            state = f"DAMAGED: {damaged[0][0]} {damaged[0][1]}" + (f" (+{len(damaged) - 1} more)" if len(damaged) > 1 else "")
        elif r.complete:
            state = "complete"
        else:
            state = f"partial {len(r.manifest['parts'])}/{r.manifest['n_tasks']}"
        who = s.holder(r.study, r.key)
        state += f", being written by {who}" if who else ""
        t.add_row(r.study, r.key[:12], r.manifest.get("config_name", "?"), str(r.rows), state,
                  r.manifest.get("created", "?"))
    for path, why in broken:
        t.add_row(path.parent.name, path.name[:12], "?", "?", f"UNREADABLE: {why}", "?")
    Console(width=max(100, Console().width)).print(t)


@runs_app.command("rm")
def runs_rm(
    key: Annotated[str, typer.Argument(help="Key prefix of the run (see `surgopt runs`).")],
    store: StoreOpt = None,
) -> None:
    """Delete one stored run (only ever inside the store root; refused while a study is writing it)."""
    import shutil

    with _guard():
        from surgopt.store import Store

        if len(key) < 4 or any(c not in "0123456789abcdef" for c in key):
            _fail(f"{key!r}: give at least 4 hex digits of a key (see `surgopt runs`)", 2)
        s = Store(store)
        matches = [r for r in s.runs() if r.key.startswith(key)]
        broken = [p for p, _ in s.unreadable() if p.name.startswith(key)]
        if len(matches) + len(broken) != 1:
            _fail(f"{key}: matches {len(matches) + len(broken)} runs in {s.root}", 2)
        if broken:
            shutil.rmtree(broken[0])
            typer.echo(f"removed {broken[0].parent.name} {broken[0].name[:12]} (its manifest was unreadable)")
            return
        s.remove(matches[0])
    typer.echo(f"removed {matches[0].study} {matches[0].key[:12]}")


@runs_app.command("gc")
def runs_gc(store: StoreOpt = None) -> None:
    """Delete partial (interrupted) runs, stray part and temporary files left by killed writers, and
    abandoned --force rebuilds. Runs that a study is writing now (their lock is held) are left alone."""
    with _guard():
        from surgopt.store import Store

        s = Store(store)
        removed = s.gc()
    typer.echo(f"removed {len(removed)} item(s)" + "".join(f"\n  {p}" for p in removed))


RunRef = Annotated[Optional[str], typer.Argument(
    help="A key prefix from `surgopt runs`, or the config that produced the run. Default: the latest run.",
    show_default=False)]
StudyOpt = Annotated[Optional[str], typer.Option("--study", help="Study name, when a config fits several.")]


@app.command("summarize")
def summarize(
    run: RunRef = None,
    store: StoreOpt = None,
    study: StudyOpt = None,
    fmt: Annotated[str, typer.Option("--format", help="table, csv, json or markdown.")] = "table",
    top: Annotated[int, typer.Option("--top", min=1, help="How many designs to list.")] = 10,
    sort: Annotated[Optional[str], typer.Option("--sort", help="Column to rank by (default: the study's objective).",
                                                show_default=False)] = None,
) -> None:
    """Summary of a stored run: top designs by the study's objective, its distribution, feasibility,
    and for studies without an objective their own comparison tables. Works on partial runs and says so."""
    if fmt not in ("table", "csv", "json", "markdown"):
        _fail(f"--format: {fmt!r} is not one of table, csv, json, markdown", 2)
    with _guard():
        from surgopt.report import render, summary_sections
        from surgopt.results import resolve_run
        from surgopt.store import Store

        st, r = resolve_run(Store(store), run, study)
        sections = summary_sections(st, r, r.parts(st.schema()), top=top, sort=sort)
    if fmt != "table":
        typer.echo(render(sections, fmt))
        return
    console = _console(260)  # the top-k table has every parameter and metric
    for title, header, rows in sections:
        _print_table(console, title, header, rows)


@app.command("plot")
def plot(
    run: RunRef = None,
    out: Annotated[Path, typer.Option("--out", help="Folder for the PNG figures.")] = Path("figures"),
    store: StoreOpt = None,
    study: StudyOpt = None,
    design: Annotated[Optional[int], typer.Option(
        "--design", help="The design_id of a study's per-design figure (raven-sweep's common workspace; "
                         "default: the best by the study's objective).",
        show_default=False)] = None,
) -> None:
    """PNG figures of a stored run in the style of its paper (each study's own; docs/figures shows them
    for the paper setups)."""
    if out.exists() and not out.is_dir():
        _fail(f"--out: {out} is a file; give a folder for the figures", 2)
    with _guard():
        from surgopt.results import config_of, resolve_run
        from surgopt.store import Store

        st, r = resolve_run(Store(store), run, study)
        table = r.read_table(st.schema())
        if table.num_rows == 0:
            _fail(f"{r.key[:12]}: the run has no rows yet", 1)
        id_column = st.key_columns[0]
        if design is not None and design not in set(table[id_column].to_pylist()):
            _fail(f"--design: no {id_column} {design} in run {r.key[:12]}", 2)
        out.mkdir(parents=True, exist_ok=True)
        paths = st.figures(config_of(st, r), table, out, design)
    for p in paths:
        typer.echo(str(p))


@app.command("check")
def check(
    config: Annotated[Path, typer.Argument(help="Config of the study to run (or reuse from the store).")],
    baseline: Annotated[Path, typer.Option("--baseline", help="Parquet baseline to compare with.")],
    rtol: Annotated[float, typer.Option("--rtol", min=0, help="Relative tolerance on float columns.")] = 1e-9,
    atol: Annotated[float, typer.Option("--atol", min=0, help="Absolute tolerance on float columns.")] = 1e-12,
    write: Annotated[bool, typer.Option("--write", help="(Re)create the baseline from this run instead.")] = False,
    store: StoreOpt = None,
    study: StudyOpt = None,
    jobs: JobsOpt = 2,
    quiet: QuietOpt = True,
) -> None:
    """Run (or reuse) a study and compare it with a stored Parquet baseline: key columns exactly, float
    columns within rtol/atol, after sorting by the key. Exit 0 within tolerance, 1 when not, 2 on bad input."""
    with _guard():
        import pyarrow.parquet as pq

        from surgopt.results import compare_tables, study_of_config, write_baseline
        from surgopt.runner import run_study
        from surgopt.store import Store

        st, cfg = study_of_config(config, study)
        if not write and not baseline.is_file():
            _fail(f"{baseline}: baseline not found (create it with --write)", 2)
        res = run_study(st, cfg, config_name=config.stem, store=Store(store), jobs=jobs, quiet=quiet,
                        say=lambda m: typer.echo(m, err=True))
        if write:
            write_baseline(res.table, st.key_columns, baseline)
            typer.echo(f"wrote {baseline} ({res.table.num_rows} rows)")
            return
        try:
            base = pq.read_table(baseline)
        except Exception as exc:  # noqa: BLE001 - any unreadable file is bad input
            _fail(f"{baseline}: not a readable Parquet file ({exc})", 2)
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


def main() -> None:
    for sig in (signal.SIGTERM, signal.SIGHUP):
        signal.signal(sig, _stop_on)
    app()


if __name__ == "__main__":
    sys.exit(main())
