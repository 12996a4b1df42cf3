"""Command line: thin Typer commands that parse, call the library and render.

Heavy imports (numpy, numba, pyarrow) happen inside the commands so that
``surgopt --help`` stays instant.
"""
from __future__ import annotations

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

StoreOpt = Annotated[Optional[Path], typer.Option(
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
ChunkOpt = Annotated[Optional[int], typer.Option(
    "--chunk-size", min=1, help="Design points per task (a resumed run keeps the size it started with).",
    show_default=False)]


def _fail(exc: BaseException, code: int) -> None:
    typer.echo(f"surgopt: error: {exc}", err=True)
    raise typer.Exit(code)


def _load_study_config(study, config: Optional[Path]):
    from surgopt.config import load_config, load_embedded

    if config is None:
        return load_embedded(study.DEFAULT_CONFIG, study.Config), f"embedded:{Path(study.DEFAULT_CONFIG).stem}"
    return load_config(config, study.Config), config.stem


@app.command("rcm-grid")
def rcm_grid(
    config: Annotated[Optional[Path], typer.Argument(
        help="TOML or YAML config. Without it: the paper's setup (121 x 121 RCM candidates, "
             "17^3-point 50 mm cube, PA10-7C, 587 mm tool).", show_default=False)] = None,
    cull: Annotated[bool, typer.Option(
        "--cull", help="Fast exact argmax with the Culling algorithm (Stocco & Salcudean) instead of "
                       "the full GII map; culled candidates carry an upper bound.")] = False,
    store: StoreOpt = None,
    jobs: JobsOpt = 2,
    force: ForceOpt = False,
    quiet: QuietOpt = False,
    chunk_size: ChunkOpt = None,
    backend: BackendOpt = "threads",
    scheduler: SchedulerOpt = None,
) -> None:
    """Global Isotropy Index of candidate remote-centre-of-motion locations for a PA10-7C
    (Locke & Patel, ICRA 2007: eqs. 5-9, Fig. 3, Table I).

    For every RCM candidate (x, z) the tool tip visits each point of a cube below the RCM with the
    tool axis through the RCM; closed-form IK (S3 = W2 = 0) and the alternative Jacobian under the RCM
    constraint give the reverse Jacobian J_r, scaled by the rated joint speeds. GII = min sigma_min /
    max sigma_max over the cube (eq. 7); a candidate with any unreachable point is infeasible.
    Rows: candidate_id, x_rcm_m, z_rcm_m, gii, feasible, sigma_min_m_per_s, sigma_max_m_per_s,
    n_unreachable, n_singular, points_evaluated, gii_is_exact.
    """
    _run_study_command("rcm-grid", config, store, jobs, force, quiet, chunk_size, backend, scheduler,
                       overrides={"search": "cull"} if cull else None)


@app.command("raven-sweep")
def raven_sweep(
    config: Annotated[Optional[Path], typer.Argument(
        help="TOML or YAML config. Without it: the paper's Table II sweep (250,000 designs: alpha, beta "
             "5-90 deg step 20; phi +-20 deg step 10; bx, by 50-200 mm step 50; Iso_min 0.1-0.9 step 0.2).",
        show_default=False)] = None,
    refine: Annotated[bool, typer.Option(
        "--refine", help="After the grid, a compass search from the top-k designs inside the sweep's bounds; "
                         "its rows are stored as a second run.")] = False,
    store: StoreOpt = None,
    jobs: JobsOpt = 2,
    force: ForceOpt = False,
    quiet: QuietOpt = False,
    chunk_size: ChunkOpt = None,
    backend: BackendOpt = "threads",
    scheduler: SchedulerOpt = None,
) -> None:
    """Raven IV port placement and link design (Li, Glozman, Milutinovic, Rosen, ICRA 2011: eqs. 1-43,
    Table II, Figs. 4, 6-8).

    For every design (alpha, beta, phi_x, phi_y, phi_z, bx, by, Iso_min) the common workspace of all arms
    on a plane 150 mm below the ports: a point belongs to an arm when its tool axis can point there with
    theta2 in the range narrowed by Iso_min and d4 <= 250 mm. Rows: the eight parameters, area_cm2,
    perimeter_cm, zeta_cm (eq. 33), iso_sum, iso_mean, iso_area_cm2, iso_min_actual, n_points,
    cost (eq. 43), source (grid | refine). Ends with the top designs and the rank of the paper's optimum.
    """
    _run_study_command("raven-sweep", config, store, jobs, force, quiet, chunk_size, backend, scheduler,
                       then_refine=refine)


@app.command("suture-sim")
def suture_sim(
    config: Annotated[Optional[Path], typer.Argument(
        help="TOML or YAML config. Without it: the paper's suturing simulation (W1 and W2, 550 and 800 mm "
             "arms, 6 mm half circle at 0.5 mm/s, dt 0.01 s).", show_default=False)] = None,
    store: StoreOpt = None,
    jobs: JobsOpt = 2,
    force: ForceOpt = False,
    quiet: QuietOpt = False,
    backend: BackendOpt = "threads",
    scheduler: SchedulerOpt = None,
) -> None:
    """Suturing with one arm of the two-armed throat robot (Wei, Xu & Simaan: eqs. 2-32, Figs. 6-7).

    Five-bar, Z-theta stage through the laryngoscope fulcrum, two constant-curvature snake segments:
    8 inputs for the 6-DoF gripper pose. Each time step takes a weighted least-norm step
    dq = W^-1 J^T (J W^-1 J^T)^-1 dx (eq. 32) with closed-loop correction. Every combination of weight
    set, arm length, fulcrum position, task mode (spin | orbit_parallel | orbit_tangent), radius and
    speed is one run. Rows: run settings, step, t_s, q1_rad..q8_rad (q3 in mm), q1_norm..q8_norm
    (|q_i / q_imax|), pos_err_mm, rot_err_deg. Ends with the joint ranges of the weight sets side by side.
    """
    _run_study_command("suture-sim", config, store, jobs, force, quiet, None, backend, scheduler)


def _run_study_command(name, config, store, jobs, force, quiet, chunk_size, backend="threads", scheduler=None,
                       overrides=None, then_refine=False):
    from surgopt.errors import SurgoptError
    try:
        from surgopt.store import Store
        from surgopt.studies import get_study
        from surgopt.runner import run_study

        study = get_study(name)
        cfg, config_name = _load_study_config(study, config)
        if overrides:
            cfg = study.Config.model_validate({**cfg.model_dump(), **overrides})
        say = lambda m: typer.echo(m, err=True)  # noqa: E731
        result = run_study(study, cfg, config_name=config_name, store=Store(store), jobs=jobs,
                           force=force, quiet=quiet, chunk=chunk_size, backend=backend, scheduler=scheduler,
                           say=say)
        _report(study, result)
        if then_refine:
            rcfg = study.refine_config(cfg, result.table)
            refined = run_study(study, rcfg, config_name=f"{config_name}+refine", store=Store(store), jobs=jobs,
                                force=force, quiet=quiet, chunk=1, backend=backend, scheduler=scheduler, say=say)
            _report(study, refined)
    except SurgoptError as exc:
        _fail(exc, exc.exit_code)
    except KeyboardInterrupt:
        typer.echo("surgopt: interrupted; finished chunks are stored, run the same command again to resume",
                   err=True)
        raise typer.Exit(130)


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
        console.print(f"cache hit: {study.NAME} {run.key[:12]} already in {run.path}")
    summary = study.summarize(result.table)
    t = Table(title=f"{study.NAME} ({run.manifest['config_name']})", show_header=False)
    for k, v in summary.items():
        t.add_row(k, f"{v:.6g}" if isinstance(v, float) else str(v))
    t.add_row("rows", str(result.table.num_rows))
    t.add_row("time_s", f"{result.elapsed_s:.2f}")
    t.add_row("store", f"{run.path}")
    console.print(t)
    for title, header, rows in study.tables(result.table):
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

    from surgopt.store import Store

    s = Store(store)
    items = s.runs(study)
    if not items:
        typer.echo(f"no runs in {s.root}")
        return
    t = Table(title=f"runs in {s.root}")
    for col in ("study", "key", "config", "rows", "state", "created"):
        t.add_column(col)
    for r in items:
        state = "complete" if r.complete else f"partial {len(r.manifest['parts'])}/{r.manifest['n_tasks']}"
        t.add_row(r.study, r.key[:12], r.manifest.get("config_name", "?"), str(r.rows), state,
                  r.manifest.get("created", "?"))
    Console(width=max(100, Console().width)).print(t)


@runs_app.command("rm")
def runs_rm(
    key: Annotated[str, typer.Argument(help="Key prefix of the run (see `surgopt runs`).")],
    store: StoreOpt = None,
) -> None:
    """Delete one stored run (only ever inside the store root)."""
    from surgopt.errors import SurgoptError
    from surgopt.store import Store

    s = Store(store)
    matches = [r for r in s.runs() if r.key.startswith(key)]
    if len(matches) != 1:
        _fail(f"{key}: matches {len(matches)} runs in {s.root}", 2)
    try:
        s.remove(matches[0])
    except SurgoptError as exc:
        _fail(exc, exc.exit_code)
    typer.echo(f"removed {matches[0].study} {matches[0].key[:12]}")


@runs_app.command("gc")
def runs_gc(store: StoreOpt = None) -> None:
    """Delete partial (interrupted) runs and temporary files left by killed writers."""
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
    and for suture runs the weight-set comparison. Works on partial runs and says so."""
    from surgopt.errors import SurgoptError

    if fmt not in ("table", "csv", "json", "markdown"):
        _fail(f"--format: {fmt!r} is not one of table, csv, json, markdown", 2)
    try:
        from surgopt.report import render, summary_sections
        from surgopt.results import resolve_run
        from surgopt.store import Store

        st, r = resolve_run(Store(store), run, study)
        sections = summary_sections(st, r, r.read_table(st.schema()), top=top, sort=sort)
    except SurgoptError as exc:
        _fail(exc, exc.exit_code)
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
        "--design", help="raven-sweep: design_id of the workspace figure (default: the best by cost).",
        show_default=False)] = None,
) -> None:
    """PNG figures of a stored run in the style of the papers: rcm-grid GII map (Fig. 3) and Table I
    scatter; raven-sweep common workspace (Figs. 4, 8), zeta over alpha-beta (Fig. 7), theta2 range against
    Iso_min (Fig. 6); suture-sim |q_i/q_imax| against time per weight set (Fig. 7) and the tracked path."""
    from surgopt.errors import SurgoptError
    try:
        from surgopt.report import figures
        from surgopt.results import config_of, resolve_run
        from surgopt.store import Store

        st, r = resolve_run(Store(store), run, study)
        table = r.read_table(st.schema())
        if table.num_rows == 0:
            _fail(f"{r.key[:12]}: the run has no rows yet", 1)
        paths = figures(st, config_of(st, r), table, out, design)
    except SurgoptError as exc:
        _fail(exc, exc.exit_code)
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
    from surgopt.errors import SurgoptError
    try:
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
            write_baseline(res.table, st.KEY_COLUMNS, baseline)
            typer.echo(f"wrote {baseline} ({res.table.num_rows} rows)")
            return
        try:
            base = pq.read_table(baseline)
        except Exception as exc:  # noqa: BLE001 - any unreadable file is bad input
            _fail(f"{baseline}: not a readable Parquet file ({exc})", 2)
        problems, diffs = compare_tables(res.table, base, st.KEY_COLUMNS, rtol, atol)
    except SurgoptError as exc:
        _fail(exc, exc.exit_code)
    for p in problems:
        typer.echo(f"FAIL: {p}")
    if diffs:
        typer.echo(f"FAIL: {len(diffs)} value(s) differ beyond rtol={rtol:g}, atol={atol:g}; worst:")
        for d in diffs[:8]:
            typer.echo(f"  {d.column} at {dict(zip(st.KEY_COLUMNS, d.key))}: baseline {d.baseline!r}, now "
                       f"{d.current!r} (relative {d.rel:.3g})")
    if problems or diffs:
        raise typer.Exit(1)
    typer.echo(f"OK: {res.table.num_rows} rows match {baseline} (rtol={rtol:g}, atol={atol:g})")


def main() -> None:
    app()


if __name__ == "__main__":
    sys.exit(main())
