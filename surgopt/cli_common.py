"""Command line, what every command shares: the Typer app and its global options, the option types and
formats, one-line error handling (``guard``: exit codes 2 bad input, 1 a failed run or store, 130 / 143 /
129 stopped) and table printing. ``surgopt.cli`` (the study commands) and ``surgopt.cli_results`` (the
commands that read the store) both import it; neither imports the other's internals. Just past 400 lines:
what both sides share is one module so that neither side imports the other.
"""
from __future__ import annotations

import contextlib
import enum
import sys
from typing import Annotated, Optional

import typer

from surgopt.interrupts import COMPLETE, RESUME, UNCHANGED  # noqa: F401 - the lines of a stopped command (light: imports nothing)

app = typer.Typer(
    name="surgopt",
    help="Kinematic design studies of surgical robots, batch-run with a cached Parquet result store.\n\n"
    "Each study command runs the paper's own setup when given no CONFIG. Results go to the store "
    "(--store, $SURGOPT_STORE, or ./surgopt-store); an identical config is a cache hit and an "
    "interrupted run resumes where it stopped.",
    no_args_is_help=True,
    add_completion=True,
    pretty_exceptions_enable=False,
)

StoreOpt = Annotated[Optional[str], typer.Option(
    "--store", envvar="SURGOPT_STORE", help="Result store folder \\[default: ./surgopt-store].",
    show_default=False)]
JobsOpt = Annotated[int, typer.Option("--jobs", "-j", min=1, max=256,
                                      help="Parallel workers: threads (threads), worker processes (loky), or LocalCluster workers (dask).")]
ForceOpt = Annotated[bool, typer.Option("--force", metavar="", help="Recompute even if the store holds this study.")]
MultirunOpt = Annotated[bool, typer.Option("--multirun", "-m", metavar="", help="Overrides with comma lists (a=1,2 b=x,y) run "
                                                                  "every combination, each its own stored run, and end "
                                                                  "with one table of them.")]
PrintConfigOpt = Annotated[bool, typer.Option("--print-config", metavar="", help="Print the effective validated config as TOML "
                                                                     "(what is hashed into the store key) and exit.")]
DryRunOpt = Annotated[bool, typer.Option("--dry-run", metavar="", help="Say what would run (size, chunks, store key, whether it "
                                                           "is stored, estimated time and memory) and exit; nothing "
                                                           "is computed or written.")]
QuietOpt = Annotated[bool, typer.Option("--quiet", "-q", metavar="", help="No progress bar.")]
TagOpt = Annotated[Optional[list[str]], typer.Option(
    "--tag", help="KEY=VALUE labels for the run (repeatable), shown by `surgopt runs`; not part of the store key.",
    show_default=False)]
NameOpt = Annotated[Optional[str], typer.Option(
    "--name", help="A name for the run, shown by `surgopt runs` (not part of the store key: a cache hit takes "
                   "the name too).", show_default=False)]
def _backend_choices() -> enum.Enum:
    """The CLI's --backend choices, derived from ``backends.BACKENDS`` (the one list; importing it loads no pool)."""
    from surgopt.backends import BACKENDS

    return enum.Enum("Backend", {name: name for name in BACKENDS}, type=str)


Backend = _backend_choices()


class SummaryFormat(str, enum.Enum):
    table = "table"
    csv = "csv"
    json = "json"
    markdown = "markdown"


ReportFormatOpt = Annotated[SummaryFormat, typer.Option(
    "--format", help="The closing report as a table (the terminal's), markdown, csv (each table under a '# title' line) or json (the headline, notes and tables as records; one document per run) on standard output; words about the run go to standard error.")]


class FigureFormat(str, enum.Enum):
    png = "png"
    pdf = "pdf"
    svg = "svg"


class ExportFormat(str, enum.Enum):
    csv = "csv"
    parquet = "parquet"
    json = "json"


BackendOpt = Annotated[Backend, typer.Option(
    "--backend", help="threads (a thread pool in this process: the kernels release the GIL, so they run "
                      "in parallel with no worker start-up), loky (local worker processes) or dask (a "
                      "distributed cluster through joblib's dask backend; needs pip install 'surgopt\\[dask]').")]
SchedulerOpt = Annotated[Optional[str], typer.Option(
    "--scheduler", help="With --backend dask: the scheduler address (tcp://host:8786). Without it, a "
                        "LocalCluster of --jobs single-threaded workers.", show_default=False)]
def _positive_finite(value: float | None) -> float | None:
    """A budget: a positive, finite number (0, -0.0, inf, nan and 1e400 are not budgets)."""
    import math

    if value is not None and not (math.isfinite(value) and value > 0):
        raise typer.BadParameter(f"{value!r} is not a budget: give a positive, finite number")
    return value


MaxHoursOpt = Annotated[float, typer.Option(
    "--max-hours", callback=_positive_finite, help="Refuse a config whose estimated work exceeds this many hours on --jobs cores "
                                 "(the estimate is printed; raise this to run it anyway).")]
MaxMemoryOpt = Annotated[Optional[float], typer.Option(
    "--max-memory-gb", callback=_positive_finite, help="Refuse a config whose estimated peak memory exceeds this "
                                     "\\[default: half of this machine's memory].", show_default=False)]
ChunkOpt = Annotated[Optional[int], typer.Option(
    "--chunk-size", min=1, help="Design points per task (a resumed run keeps the size it started with).",
    show_default=False)]


def _version(value: bool) -> None:
    if value:
        from surgopt import __version__

        typer.echo(f"surgopt {__version__}")
        raise typer.Exit()


#: -v / -vv: the runner's and store's log on stderr, given before the subcommand or after it.
VerboseOpt = Annotated[int, typer.Option("--verbose", "-v", count=True, metavar="",
                                         help="Say what the runner and store do (resumed parts, cache hits, chunk "
                                              "sizes) on stderr; -vv for every part.")]


def set_verbosity(verbose: int) -> None:
    if verbose:
        import logging

        logging.basicConfig(level=logging.DEBUG if verbose > 1 else logging.INFO, stream=sys.stderr,
                            format="surgopt: %(message)s", force=True)


@app.callback()
def _main_options(
    version: Annotated[bool, typer.Option("--version", metavar="", callback=_version, is_eager=True,
                                          help="Print the version and exit.")] = False,
    verbose: VerboseOpt = 0,
) -> None:
    """Kinematic design studies of surgical robots, batch-run with a cached Parquet result store.

    Each study command runs the paper's own setup when given no CONFIG. Results go to the store (--store,
    $SURGOPT_STORE, or ./surgopt-store); an identical config is a cache hit and an interrupted run resumes
    where it stopped.
    """
    set_verbosity(verbose)


#: A phase says what it does once it has taken this long, then every ANNOUNCE_EVERY_S (issue 56 item 5).
ANNOUNCE_AFTER_S = 2.0
ANNOUNCE_EVERY_S = 15.0


@contextlib.contextmanager
def announced(what: str, say=None, quiet: bool = False):
    """``what`` (e.g. "building the closing report of port-place run 734f48b5c35e") said on stderr, with the time
    so far, once the phase inside has taken ANNOUNCE_AFTER_S and every ANNOUNCE_EVERY_S after (from a daemon
    thread: the phase itself may hold the GIL in numpy or numba, which let it go); silent for a quick phase, and
    with ``quiet`` (--quiet)."""
    if quiet:
        yield
        return
    import threading
    import time

    say = say or (lambda m: typer.echo(m, err=True))
    done = threading.Event()
    t0 = time.monotonic()

    def speak():
        wait = ANNOUNCE_AFTER_S
        while not done.wait(wait):
            say(f"{what} ... ({time.monotonic() - t0:.0f} s)")
            wait = ANNOUNCE_EVERY_S

    thread = threading.Thread(target=speak, name="surgopt-announce", daemon=True)
    thread.start()
    try:
        yield
    finally:
        done.set()


def fail(exc: BaseException, code: int) -> None:
    typer.echo(f"surgopt: error: {exc}", err=True)
    raise typer.Exit(code)




@contextlib.contextmanager
def guard(stores: bool = True):
    """Every failure a command can meet ends in one line on stderr and an exit code: 2 bad input,
    1 a failed run or store, 130 / 143 / 129 interrupted by SIGINT / SIGTERM / SIGHUP. ``stores``: whether the
    command stores a run's chunks (its lines then say a resume finds them; else ``UNCHANGED``). A study command
    says ``interrupts.on_stop`` as it goes: UNCHANGED while it reads its configs or estimates (a dry run),
    RESUME while a run stores, COMPLETE once it is stored."""
    from surgopt import interrupts
    from surgopt.errors import SurgoptError, out_of_memory

    interrupts.on_stop(RESUME if stores else UNCHANGED)
    try:
        yield
    except KeyboardInterrupt as exc:  # Ctrl-C, or SIGTERM / SIGHUP (surgopt.interrupts.Stopped)
        raise typer.Exit(interrupts.report(exc))
    except Exception as exc:  # noqa: BLE001 - re-raised below unless it is a stop's consequence or ours to word
        if interrupts.received() is not None:
            # what failed while a stop unwound is the stop: a lock file mid-rename, a library that wraps the
            # KeyboardInterrupt raised inside it (pydantic-core building a validator: SchemaError)
            raise typer.Exit(interrupts.report(None)) from None
        if not isinstance(exc, (SurgoptError, OSError)) and not out_of_memory(exc):
            raise
        fail_on(exc, interrupts.stop_hint() == RESUME)


def fail_on(exc: BaseException, stores: bool = True) -> None:
    """One line and the exit code for a library error, out of memory, or an OS error (``stores``: as ``guard``)."""
    from surgopt.errors import SurgoptError, out_of_memory
    from surgopt.store import is_disk_full

    if isinstance(exc, SurgoptError):
        fail(exc, exc.exit_code)
    if out_of_memory(exc):
        fail("out of memory; what finished before it is stored (`surgopt runs` says how much): run the same "
             "command again with more memory, a smaller config or --jobs 1" if stores else
             f"out of memory; {UNCHANGED} with more memory free", 1)
    where = f" writing {exc.filename}" if getattr(exc, "filename", None) else ""
    if is_disk_full(exc):
        fail(f"the disk is full{where}; {RESUME if stores else UNCHANGED} once there is space", 1)
    fail(f"{getattr(exc, 'strerror', None) or exc}{where}", 1)


def wide_console(min_width: int = 150):
    """A console at the terminal's width; piped, wide enough for the tables (``print_table`` sizes each one)."""
    from rich.console import Console

    c = Console()
    return c if c.is_terminal else Console(width=columns_env() or max(c.width, min_width))


def columns_env() -> int | None:
    """The width a user set in COLUMNS (20 to 1,000 characters), else None: a piped table honours it."""
    import os

    try:
        width = int(os.environ.get("COLUMNS", ""))
    except ValueError:
        return None
    return width if 20 <= width <= 1000 else None


#: The narrowest a table's first column (its labels) is folded to when the table must fit a terminal.
LABEL_MIN = 24
#: The narrowest a column of words (a clinical number and its source, a port "in words") is folded to: such a
#: column wraps rather than being left out (issue 56 item 8: the clinical number beside each check was dropped).
WORDS_MIN = 16


def words_column(values: list[str]) -> bool:
    """A column of words, which may wrap: some cell holds a letter and a space ("54 right, 36 cranial"); numbers,
    ranges of numbers and one-word flags ("yes", "OUTSIDE") never wrap."""
    return any(" " in v and any(ch.isalpha() for ch in v) for v in values)


def print_table(console, title, header, rows) -> None:
    """A table that never cuts a number or stacks a header letter by letter: to a pipe or a file at its own width;
    on a terminal too narrow for it, a one- or two-row table turned on its side, else the first column and as
    many others as fit, with a line naming the columns left out (issue 42: 14 columns squeezed into 80)."""
    from rich.console import Console
    from rich.table import Table

    header = [str(h) for h in header]
    rows = [[str(v) for v in row] for row in rows]
    def shape():  # each column's width, whether it is words, and the least width the whole table folds to
        widths = [max([len(header[i])] + [len(r[i]) for r in rows if i < len(r)]) for i in range(len(header))]
        words = [i > 0 and words_column([r[i] for r in rows if i < len(r)]) for i in range(len(header))]
        least = sum((min(w, LABEL_MIN) if i == 0 else min(w, WORDS_MIN) if words[i] else w) + 3
                    for i, w in enumerate(widths)) + 1
        return widths, words, least

    widths, words, least = shape()
    need = sum(w + 3 for w in widths) + 1
    if not console.is_terminal:  # a pipe or a file: its own width, or the COLUMNS a user set (issue 56 item 8)
        console = Console(width=columns_env() or max(need, len(title or "") + 4, 80), file=console.file,
                          force_terminal=False)
    omitted = []
    if least > console.width and 1 <= len(rows) <= 2 and len(header) > 2:
        header, rows = ["field", *(["value"] if len(rows) == 1 else ["row 1", "row 2"])], \
            [[h, *[r[i] for r in rows]] for i, h in enumerate(header)]
        widths, words, least = shape()
    elif least > console.width:  # the first column (a label) may wrap down to LABEL_MIN, words down to WORDS_MIN;
        keep, used = [0], min(widths[0], LABEL_MIN) + 4  # numbers never wrap
        for i in range(1, len(header)):
            least = min(widths[i], WORDS_MIN) if words[i] else widths[i]
            if used + least + 3 <= console.width:
                keep.append(i)
                used += least + 3
            else:
                omitted.append(header[i])
        header, rows, widths, words = ([header[i] for i in keep], [[r[i] for i in keep] for r in rows],
                                       [widths[i] for i in keep], [words[i] for i in keep])
    t = Table(title=title)
    for i, h in enumerate(header):
        least = min(widths[0], LABEL_MIN) if i == 0 else min(widths[i], WORDS_MIN) if words[i] else None
        t.add_column(h, justify="left" if i == 0 or words[i] else "right", no_wrap=i > 0 and not words[i], overflow="fold",
                     min_width=least)
    for row in rows:
        t.add_row(*row)
    console.print(t)
    if omitted:
        console.print(f"({len(omitted)} more column(s) not shown at {console.width} columns: {', '.join(omitted)}; "
                      f"widen the terminal, or use --format csv / json)", highlight=False)


def emit_tables(fmt: str, items) -> None:
    """What a command prints: ``items``, each a table (title, header, rows) or a line of words, in ``fmt`` (issue 56
    item 8: every command that prints a table takes --format): ``table`` as the terminal's (``print_table``), the
    words between them; ``csv`` (each table under a '# title' line) or ``markdown`` on standard output with the
    words on standard error, so that a pipe reads the tables alone."""
    from surgopt.report import render

    if fmt == "table":
        console = wide_console(0)
        for item in items:
            if isinstance(item, str):
                typer.echo(item)
            else:
                print_table(console, *item)
        return
    for item in items:
        if isinstance(item, str):
            typer.echo(item, err=True)
    typer.echo(render([item for item in items if not isinstance(item, str)], fmt))


def print_report(study_name: str, run, summary, edges, front, *, rows: int, elapsed_s: float, cache_hit: bool,
                 messages=(), brief: bool = False, fmt: str = "table") -> None:
    """The closing report's text: the run's messages, the headline table, the best-on-an-edge notes and (unless
    ``brief``) the study's tables and a search's front (also what ``surgopt.hits`` prints for a recorded
    command line)."""
    from rich.table import Table

    if fmt != "table":
        return print_report_as(fmt, study_name, run, summary, edges, front, rows=rows, elapsed_s=elapsed_s,
                               cache_hit=cache_hit, messages=messages, brief=brief)
    console = wide_console()
    for m in messages:
        console.print(m)
    if cache_hit:
        console.print(f"cache hit: {study_name} {run.key[:12]} already in {run.path}")
    from rich.markup import escape

    t = Table(title=escape(f"{study_name} ({run.manifest['config_name']})"), show_header=False)
    for k, v in summary.headline.items():  # a value may hold "[search]": text, not markup
        t.add_row(k, f"{v:.6g}" if isinstance(v, float) else escape(str(v)))
    t.add_row("rows", str(rows))
    t.add_row("time_s", f"{elapsed_s:.2f}")
    t.add_row("store", f"{run.path}")
    console.print(t)
    for note in edges:
        console.print(f"note: {escape(note)}")
    if not brief:
        for title, header, table_rows in summary.tables:
            print_table(console, title, header, table_rows)
        if front is not None:
            print_table(console, *front)


def report_sections(study_name: str, run, summary, edges, front, *, rows: int, elapsed_s: float,
                    brief: bool = False) -> list:
    """The closing report as (title, header, rows) sections, in the order ``print_report`` prints them: the
    headline (field, value), the notes, then (unless ``brief``) the study's tables and a search's front."""
    head = [[k, v] for k, v in summary.headline.items()] + [["rows", rows], ["time_s", round(elapsed_s, 2)],
                                                           ["store", str(run.path)]]
    sections = [(f"{study_name} ({run.manifest['config_name']})", ["field", "value"], head)]
    if edges:
        sections.append(("notes", ["note"], [[n] for n in edges]))
    if not brief:
        sections += [tuple(t) for t in summary.tables]
        if front is not None:
            sections.append(tuple(front))
    return sections


def print_report_as(fmt: str, study_name: str, run, summary, edges, front, *, rows: int, elapsed_s: float,
                    cache_hit: bool, messages=(), brief: bool = False) -> None:
    """The closing report in ``fmt`` (markdown, csv, json) on standard output, the run's messages and the cache hit
    on standard error (so a pipe reads the report alone). JSON: {study, run_key, config_name, headline, notes,
    tables: {title: [record, ...]}} with the headline's values as they are (numbers stay numbers)."""
    import json

    from surgopt.report import render

    for m in messages:
        typer.echo(m if isinstance(m, str) else str(m), err=True)
    if cache_hit:
        typer.echo(f"cache hit: {study_name} {run.key[:12]} already in {run.path}", err=True)
    sections = report_sections(study_name, run, summary, edges, front, rows=rows, elapsed_s=elapsed_s, brief=brief)
    if fmt == "json":
        doc = {"study": study_name, "run_key": run.key, "config_name": run.manifest.get("config_name"),
               "headline": {**summary.headline, "rows": rows, "time_s": round(elapsed_s, 2), "store": str(run.path)},
               "notes": list(edges),
               "tables": {title: [dict(zip(header, r)) for r in body] for title, header, body in sections[1:]
                          if title != "notes"}}
        typer.echo(json.dumps(doc, indent=1, default=str))
        return
    typer.echo(render(sections, fmt))
