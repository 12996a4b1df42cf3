"""Command line: thin Typer commands that parse, call the library and render.

This module: the app, the shared options, one-line error handling (``guard``), and the study
commands built from the registry (overrides, --multirun, --print-config, --dry-run). The commands
that read the store are in ``surgopt.cli_results``. Heavy imports (numba, pyarrow) happen inside the
commands so that ``surgopt --help`` stays fast.

One module of ~600 lines because the study commands are one flow (compose, estimate, run, report, record the
hit) that every study's command is built from; splitting it would pass that flow's state between modules.
"""
from __future__ import annotations

import contextlib
import sys
from dataclasses import dataclass
from typing import Annotated, Optional

import typer
from typer.core import TyperGroup

from surgopt.cli_common import (  # noqa: F401 - app and the options: the commands below register on them
    COMPLETE, RESUME, UNCHANGED, Backend, BackendOpt, ChunkOpt, DryRunOpt, ForceOpt, JobsOpt, MaxHoursOpt, MaxMemoryOpt, MultirunOpt,
    NameOpt, PrintConfigOpt, ReportFormatOpt, SummaryFormat, TagOpt, QuietOpt, SchedulerOpt, StoreOpt, VerboseOpt,
    announced, app, guard, print_report,
    print_table,
    set_verbosity, wide_console,
)

def _study_command(name: str):
    """The click command ``surgopt <name>``: CONFIG and KEY=VALUE overrides, the study's own flags, the shared
    options.

    The command's signature is built from the study's declaration (``Study.flags``, ``Study.chunked``),
    so this module names no study.
    """
    import inspect

    from surgopt.studies import get_study

    study = get_study(name)

    P = inspect.Parameter
    params = [P("args", P.KEYWORD_ONLY, default=None, annotation=Annotated[Optional[list[str]], typer.Argument(
        help=_literal(f"{study.config_help} Several CONFIG files are merged in order, the later over the earlier "
                      f"(a patient file, then a region file). Then any KEY=VALUE overrides (dotted keys, e.g. "
                      f"{_example_override(study.config_model)}; a comma list with --multirun)."),
        show_default=False, metavar="[CONFIG ...] [KEY=VALUE]")])]
    params += [P(f.dest, P.KEYWORD_ONLY, default=None if f.metavar else False,
                 annotation=Annotated[Optional[str], typer.Option(f.option, help=_literal(f.help), metavar=f.metavar,
                                                                  show_default=False)]
                 if f.metavar else Annotated[bool, typer.Option(f.option, metavar="", help=_literal(f.help))])
               for f in study.flags]
    shared = [("multirun", MultirunOpt, False), ("print_config", PrintConfigOpt, False), ("dry_run", DryRunOpt, False),
              ("store", StoreOpt, None), ("jobs", JobsOpt, 2), ("force", ForceOpt, False), ("quiet", QuietOpt, False),
              ("name", NameOpt, None), ("tag", TagOpt, None), ("verbose", VerboseOpt, 0),
              ("fmt", ReportFormatOpt, SummaryFormat.table)]
    if study.chunked:
        shared.append(("chunk_size", ChunkOpt, None))
    shared += [("backend", BackendOpt, Backend.threads), ("scheduler", SchedulerOpt, None),
               ("max_hours", MaxHoursOpt, 1.0), ("max_memory_gb", MaxMemoryOpt, None)]
    params += [P(name, P.KEYWORD_ONLY, default=default, annotation=ann) for name, ann, default in shared]

    def command(**kw) -> None:
        given = [(f, kw.pop(f.dest)) for f in study.flags]
        given = [(f, v) for f, v in given if v not in (None, False)]
        _run_study_command(study, StudyCommand(**kw), given)

    command.__signature__ = inspect.Signature(params)
    command.__annotations__ = {p.name: p.annotation for p in params}
    command.__doc__ = _literal(_reflow(study.help))
    command.__name__ = study.name.replace("-", "_")
    one = typer.Typer(rich_markup_mode=app.rich_markup_mode, pretty_exceptions_enable=False, add_completion=False)
    one.command(study.name, cls=_other_studies_flags(study.name))(command)
    return typer.main.get_command(one)


def _other_studies_flags(name: str):
    """A study command that answers a flag of another study (``port-place --robot ur5e``: click suggested
    --jobs, --verbose) by saying whose flag it is and where this study takes that choice."""
    from typer.core import TyperCommand

    class Command(TyperCommand):
        def parse_args(self, ctx, args):
            try:
                return super().parse_args(ctx, args)
            except Exception as exc:  # click's NoSuchOption (typer carries its own click)
                if type(exc).__name__ != "NoSuchOption":
                    raise
                from surgopt.studies import STUDIES, get_study

                owners = [s for s in STUDIES if s != name
                          and any(exc.option_name == f.option for f in get_study(s).flags)]
                if owners:
                    exc.message = (f"{exc.option_name} is a flag of {' and '.join(owners)}, not of {name}: {name} "
                                   f"takes that choice from its config (see `surgopt {name} --help` and "
                                   f"--print-config)")
                    exc.possibilities = None
                raise

    return Command


def _literal(text: str) -> str:
    """Help text shown as written: Rich would read "[robot]" or "[track]" as markup and drop it."""
    return text.replace("[", "\\[")


def _example_override(model) -> str:
    """A dotted KEY=VALUE of this study's own config (its first section's first number), for the help."""
    for name, info in model.model_fields.items():
        sub = info.annotation
        if isinstance(sub, type) and hasattr(sub, "model_fields"):
            for leaf, leaf_info in sub.model_fields.items():
                value = leaf_info.default
                if isinstance(value, (int, float)) and not isinstance(value, bool):
                    return f"{name}.{leaf}={value:g}"
    return "section.field=value"


def _reflow(text: str) -> str:
    """A docstring's paragraphs as single lines (the help renderer wraps them to the terminal)."""
    import inspect

    return "\n\n".join(" ".join(p.split()) for p in inspect.cleandoc(text).split("\n\n"))


def _is_config(arg: str) -> bool:
    """Whether a study command's argument is a config file rather than a KEY=VALUE override: it has no "=", or
    it is a TOML/YAML file that exists (my=cfg.toml is a file)."""
    from pathlib import Path

    p = Path(arg)
    return "=" not in arg or (p.suffix.lower() in (".toml", ".yaml", ".yml") and p.is_file())


def _split_args(args: list[str] | None) -> tuple[Optional[str | list], list[str]]:
    """[CONFIG ...] [KEY=VALUE ...]: the leading arguments that are config files (one, or several merged in order,
    the later over the earlier), then the overrides."""
    args = list(args or [])
    configs = []
    while args and _is_config(args[0]):
        configs.append(args.pop(0))
    bad = [a for a in args if "=" not in a]
    if bad:
        from surgopt.errors import UsageError

        raise UsageError(f"{bad[0]!r}: config files come first (CONFIG ...), then KEY=VALUE overrides")
    return (None if not configs else configs[0] if len(configs) == 1 else configs), args


@dataclass(frozen=True)
class StudyCommand:
    """What a study command was given (its shared options; the study's own flags travel beside it): the config
    and overrides (``args``), the store, how to run (``jobs``, ``backend``, ``scheduler``, ``chunk_size``,
    ``force``, ``quiet``), the budget (``max_hours``, ``max_memory_gb``), what to do instead of running
    (``multirun``, ``print_config``, ``dry_run``), and the run's ``name`` and ``tag``s."""

    args: list | None = None
    store: object = None
    jobs: int = 2
    force: bool = False
    quiet: bool = False
    chunk_size: int | None = None
    backend: object = "threads"
    scheduler: str | None = None
    max_hours: float = 1.0
    max_memory_gb: float | None = None
    multirun: bool = False
    print_config: bool = False
    dry_run: bool = False
    name: str | None = None
    tag: list | None = None
    verbose: int = 0
    fmt: object = "table"  # the closing report's format (``--format``)

    def run_options(self, **fields):
        """The runner's ``RunOptions`` of this command (``fields``: a run's own name or tags)."""
        from surgopt.runner import RunOptions

        return RunOptions(jobs=self.jobs, backend=getattr(self.backend, "value", self.backend),
                          scheduler=self.scheduler, chunk=self.chunk_size, force=self.force, quiet=self.quiet,
                          max_hours=self.max_hours, max_memory_bytes=None if self.max_memory_gb is None
                          else int(self.max_memory_gb * 2 ** 30), **fields)


def _run_study_command(study, cmd: StudyCommand, flags=()):
    set_verbosity(cmd.verbose)
    from surgopt import interrupts

    with guard():
        interrupts.on_stop(UNCHANGED)  # reading configs, estimating: nothing stored yet
        tags = _tags(cmd.tag)
        from surgopt.compose import variants
        from surgopt.runner import run_study
        from surgopt.store import Store

        options = cmd.run_options()
        config, overrides = _split_args(cmd.args)
        updates = {k: v for f, value in flags for k, v in f.update(value).items()}
        flags_text = " ".join(f"{f.option} {v}" for f, v in flags if f.value_update is not None)
        flags = [f for f, _ in flags]
        from surgopt.files import recording

        with recording() as files_read:
            given = variants(study, config, overrides, updates, multirun=cmd.multirun, flags_text=flags_text)
            todo = _expanded(study, given, flags)
        if cmd.print_config:
            from surgopt.compose import origins

            _print_configs(todo, origins(study, config, overrides, updates, flags_text))
            return
        notes = [n for v in todo if study.advice for n in study.advice(v.config)]
        for note in dict.fromkeys(notes):  # once each, in order (the runs of a --multirun often share one)
            typer.echo(f"note: {note}", err=True)
        if cmd.dry_run:
            _dry_run(study, todo, Store(cmd.store), options)
            return
        say = lambda m: typer.echo(m, err=True)  # noqa: E731
        finished, added = [], False  # added: a closing report said more than the run's kept summary
        for v in todo:
            run_name = cmd.name if cmd.name is None or len(todo) == 1 else f"{cmd.name}[{len(finished)}]"
            interrupts.on_stop(RESUME)
            result = run_study(study, v.config, config_name=v.config_name, store=Store(cmd.store), options=options,
                               say=say, name=run_name, tags=tags)
            interrupts.on_stop(COMPLETE if result.run.complete else RESUME)
            summary = _report(study, result, brief=len(todo) > 1, quiet=cmd.quiet,
                              fmt=getattr(cmd.fmt, "value", cmd.fmt), cfg=v.config)
            added = added or summary.added
            finished.append((v, result, summary))
            for f in flags:
                if f.follow_up is None:
                    continue
                from surgopt.plans import follow_up_plan

                interrupts.on_stop(RESUME)
                follow = run_study(study, v.config, plan=follow_up_plan(f.follow_up, study, v.config, result),
                                   config_name=v.config_name + f.follow_up_suffix, store=Store(cmd.store),
                                   options=options, chunk=None, say=say)
                interrupts.on_stop(COMPLETE if follow.run.complete else RESUME)
                _report(study, follow, quiet=cmd.quiet, fmt=getattr(cmd.fmt, "value", cmd.fmt))
        if len(todo) > 1 and getattr(cmd.fmt, "value", cmd.fmt) == "table":  # else each run's report alone
            _multirun_table(study, finished)
            _best_of(study, finished)
        elif _plain(cmd, flags) and todo == given and finished[0][1].run.complete and not added:
            from surgopt.hits import record

            record(Store(cmd.store), study.name, list(cmd.args or []), finished[0][1].run, files_read,
                   list(dict.fromkeys(notes)))


def _plain(cmd: StudyCommand, flags) -> bool:
    """Whether a study command was given nothing but configs, overrides and --store (``surgopt.hits`` answers
    such a command line again from the store without loading the study)."""
    return not flags and cmd == StudyCommand(args=cmd.args, store=cmd.store, backend=cmd.backend) \
        and getattr(cmd.backend, "value", cmd.backend) == "threads"


def _expanded(study, todo, flags) -> list:
    """Each config into several runs where a flag expands it (``--branches``), given or implied by the config
    (said in a note; an implied expansion that finds nothing leaves the config as it is, its advice says why)."""
    from surgopt.compose import Variant
    from surgopt.errors import UsageError

    given = {id(f) for f in flags}
    for f in study.flags:
        if f.expand is None:
            continue
        out = []
        for v in todo:
            why = None if id(f) in given or f.implied is None else f.implied(v.config)
            if id(f) not in given and why is None:
                out.append(v)
                continue
            try:
                pairs = f.expand(v.config)
            except UsageError:
                if why is None:
                    raise
                out.append(v)
                continue
            if why is not None:
                typer.echo(f"note: {why} ({len(pairs)} runs; {f.option} is implied)", err=True)
            out += [Variant(c, f"{v.config_name}+{label}", {**v.varied, **dict([label.split("=", 1)])})
                    for label, c in pairs]
        todo = out
    return todo


def _tags(given: list[str] | None) -> dict[str, str] | None:
    """--tag KEY=VALUE ... as a dict (a UsageError naming a malformed one)."""
    from surgopt.errors import UsageError

    if not given:
        return None
    out = {}
    for t in given:
        k, sep, v = t.partition("=")
        if not sep or not k.strip() or len(t) > 200:
            raise UsageError(f"--tag {t[:80]!r}: give KEY=VALUE (at most 200 characters)")
        out[k.strip()] = v.strip()
    return out


def _best_of(study, finished) -> None:
    """The best of several runs by the study's headline best objective (``best_<objective>``), when it has one."""
    key = f"best_{study.objective}"
    scored = [(s.headline[key], v) for v, _, s in finished if isinstance(s.headline.get(key), (int, float))]
    if scored:
        value, v = max(scored, key=lambda t: t[0])
        wide_console().print(f"best of the {len(finished)} runs by {key}: {value:.6g} ({v.config_name})")


def _print_configs(todo, origins: dict[str, str] | None = None) -> None:
    """The effective validated configs as TOML: exactly what is hashed (``--print-config``), after a comment
    saying where each value given came from (``compose.origins``); every other value is its field's default."""
    from surgopt.config import to_toml

    if origins:
        width = max(map(len, origins))
        typer.echo("# where each value given came from (every value not listed is its field's default):")
        for key, source in origins.items():
            typer.echo(f"#   {key:<{width}}  {source}")
    for v in todo:
        if len(todo) > 1:
            typer.echo(f"# {v.config_name}")
        typer.echo(to_toml(v.config.model_dump(mode="json")))


def _dry_run(study, todo, store, options) -> None:
    """What each run would be: size, chunks, store key and state, estimated time and memory (the whole
    process tree's: the backend's worker processes counted)."""
    from surgopt.config import study_key
    from surgopt.plans import estimate as plan_estimate
    from surgopt.plans import plan_for
    from surgopt.runner import check_budget, duration_text, run_bytes, usable_jobs, wall_seconds

    backend, scheduler, chunk_size = options.backend, options.scheduler, options.chunk
    jobs = usable_jobs(options.jobs, backend, scheduler, say=lambda m: wide_console().print(m))

    rows = []
    for v in todo:
        key = study_key(study.name, v.config, study.kernel_version)
        try:
            run = store.open(study.name, key)
        except Exception:  # noqa: BLE001 - an unusable manifest is "would be rebuilt"
            run = None
        state = "not stored" if run is None else ("stored (a cache hit)" if run.complete
                                                  else f"partial {len(run.manifest['parts'])}/{run.manifest['n_tasks']}")
        plan = plan_for(study, v.config)
        chunk = chunk_size or (run.manifest["chunk"] if run else plan.chunk(study, v.config))
        est = plan_estimate(study, v.config, plan)
        try:
            check_budget(study, v.config, jobs, options.max_hours, options.max_memory_bytes, est=est,
                         backend=backend, scheduler=scheduler)
            verdict = "within budget"
        except Exception as exc:  # noqa: BLE001 - shown, not raised: this is a dry run
            verdict = f"REFUSED: {str(exc).split(';')[0]}"
        rows.append([v.config_name, f"{est.items:,} {est.what}" if est else "?", plan.n_parts(study, v.config, chunk),
                     key[:12], state, duration_text(wall_seconds(est, jobs, overhead=not rows)) if est else "?",
                     (f"{run_bytes(est, backend, jobs, scheduler) / 2 ** 20:,.0f} MB"
                      + (f" (at most {(run_bytes(est, backend, jobs, scheduler) - est.peak_bytes + est.peak_bytes_bound) / 2 ** 20:,.0f} MB were every row stored)"
                         if est.peak_bytes_bound else "")) if est else "?", verdict])
    print_table(wide_console(), f"{study.name} --dry-run (nothing computed or written)",
                 ["config", "size", "parts", "key", "store", f"time on {jobs} core(s)", "peak memory", "budget"], rows)


def _multirun_table(study, finished) -> None:
    """One row per run of a --multirun: the varied values and the run's headline numbers."""
    keys = [k for k in finished[0][0].varied if len({repr(v.varied[k]) for v, _, _ in finished}) > 1]
    heads = [k for k, v in finished[0][2].headline.items() if isinstance(v, (int, float)) and not isinstance(v, bool)]
    rows = []
    for v, result, summary in finished:
        rows.append([str(v.varied[k]) for k in keys] + [result.run.key[:12]]
                    + [f"{summary.headline.get(h):.6g}" if isinstance(summary.headline.get(h), float)
                       else str(summary.headline.get(h, "")) for h in heads])
    print_table(wide_console(), f"{study.name} --multirun: {len(finished)} runs", keys + ["key"] + heads, rows)
    seen: dict = {}
    for v, _, summary in finished:  # the same headline: the same answer (two seeds on one branch, say)
        numbers = tuple(f"{x:.9g}" if isinstance(x, float) else x for x in map(summary.headline.get, heads))
        label = " ".join(f"{k}={v.varied[k]}" for k in keys)
        if heads and numbers in seen:
            wide_console().print(f"note: {label} gives the headline numbers of {seen[numbers]} (to 9 digits: the "
                                 f"same best; their other rows may still differ)")
        seen.setdefault(numbers, label)


class _StudyCommands(TyperGroup):
    """The app's commands, each study's built from its declaration only when that study is run or its own help
    is asked for: ``surgopt --help`` lists the studies from their packages' ``HELP`` without importing them
    (numpy, pydantic and five configs: issue 42 item 5), and ``surgopt port-place`` imports port-place alone."""

    _listing = False

    def list_commands(self, ctx):
        from surgopt.studies import STUDIES

        return [*STUDIES, *(c for c in super().list_commands(ctx) if c not in STUDIES)]

    def get_command(self, ctx, name):
        from surgopt.studies import STUDIES

        if name in STUDIES and name not in self.commands:
            if self._listing:
                return _listed_study(name)
            self.add_command(_study_command(name), name)
        return super().get_command(ctx, name)

    def resolve_command(self, ctx, args):
        """As Typer's, with "Did you mean" drawn from every command, the studies not yet loaded too (Typer's looks
        only at the commands already built: ``surgopt port-placee`` had no suggestion, issue 56 item 10)."""
        from difflib import get_close_matches

        try:
            return self._click_resolve_command(ctx, args)
        except Exception as exc:  # noqa: BLE001 - Typer's own click's UsageError (it vendors click), re-raised
            if not isinstance(getattr(exc, "message", None), str):
                raise
            matches = get_close_matches(args[0], self.list_commands(ctx)) if args else []
            if matches and "Did you mean" not in exc.message:
                exc.message = f"{exc.message.rstrip('.')}. Did you mean {', '.join(repr(m) for m in matches)}?"
            raise

    def format_help(self, ctx, formatter):
        self._listing = True
        try:
            return super().format_help(ctx, formatter)
        finally:
            self._listing = False


def _listed_study(name: str):
    """A study's line in the top-level help: its name and help (from the study package, not its declaration)."""
    import importlib

    from typer.core import TyperCommand

    from surgopt.studies import STUDIES

    package = importlib.import_module(STUDIES[name].rpartition(".")[0])
    return TyperCommand(name, help=_literal(_reflow(package.HELP)))


app.info.cls = _StudyCommands


def _report(study, result, brief: bool = False, quiet: bool = False, fmt: str = "table", cfg=None):
    """The closing report of one run (``brief``: headline only, for each run of a --multirun; ``quiet``: no word
    while it is built; ``cfg``: the config the user gave, for ``Study.config_report``'s additions, which are shown,
    not kept beside the run)."""
    run = result.run
    from surgopt.errors import StoreError

    try:
        with announced(f"the closing report of {study.name} run {run.key[:12]} ({result.parts.num_rows:,} rows)",
                       quiet=quiet):
            summary, edges, front = _closing_numbers(study, run, result.parts, brief)
    except StoreError:
        from surgopt.store import manifest_of

        if manifest_of(run.path).exists():
            raise
        for m in result.messages:
            wide_console().print(m)
        # removed (`surgopt runs rm`) between its last part and this report: the run did finish; nothing to show
        typer.echo(f"note: {study.name} run {run.key[:12]} finished, but was removed (surgopt runs rm) before its "
                   f"report could read it", err=True)
        from surgopt.studies import Summary

        return Summary({}, {})
    if run.complete and "headline" not in run.manifest:  # kept for `runs --compare`, the index, duckdb
        from surgopt.store import Store

        Store(run.path.parent.parent).record_headline(run, summary.headline)
    if study.config_report is not None and cfg is not None:  # shown, not kept: such a command is not answered
        summary = summary.with_added(study.config_report(cfg, result.parts))  # from ``_hits``
    print_report(study.name, run, summary, edges, front, rows=result.parts.num_rows, elapsed_s=result.elapsed_s,
                 cache_hit=result.cache_hit, messages=result.messages, brief=brief, fmt=fmt)
    return summary


def _closing_numbers(study, run, parts, brief: bool):
    """(Summary, best-on-an-edge notes, Pareto front or None) of a run: derived from its rows once, then kept
    beside the run (``surgopt.derived``: a cache hit of a 2.2 M-row run does not read its rows again)."""
    from surgopt.derived import derived
    from surgopt.report import run_edges, run_summary, search_front

    with _reading_rows(parts, quiet=not sys.stderr.isatty()) as watched:
        summary, edges = run_summary(study, run, watched), run_edges(study, run, watched)
        front = None if brief else derived(run, "search_front", lambda: search_front(study, run, watched))
    return summary, edges, (tuple(front) if front is not None else None)


#: Rows past which reading a run back for its report shows a progress line (a 2.2 M-row run takes seconds).
REPORT_PROGRESS_ROWS = 200_000


@contextlib.contextmanager
def _reading_rows(parts, quiet: bool):
    """``parts`` that advance a transient progress line on stderr as the report reads them back (every pass:
    rows read, elapsed), for runs of REPORT_PROGRESS_ROWS or more on a terminal."""
    if quiet or parts.num_rows < REPORT_PROGRESS_ROWS:
        yield parts
        return
    from rich.console import Console
    from rich.progress import Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

    with Progress(SpinnerColumn(), TextColumn("reading {task.completed:,.0f} rows back for the report"),
                  TimeElapsedColumn(), console=Console(stderr=True), transient=True) as progress:
        bar = progress.add_task("report", total=None)
        yield parts.watched(lambda n: progress.advance(bar, n))


@app.command("warm")
def warm(
    studies: Annotated[Optional[list[str]], typer.Argument(
        help="Studies whose kernels to compile (default: every study).", show_default=False,
        metavar="[STUDY]...")] = None,
    verbose: VerboseOpt = 0,
) -> None:
    """Compile every kernel a study's runs use once, now (its embedded default and the variants whose kernels
    differ: another metric, a generic arm, a serial arm), into the numba cache ($NUMBA_CACHE_DIR or
    ~/.cache/surgopt/numba), so that no later run compiles. Worth it after an install or an update, or before
    starting several runs at once. The kernels are compiled one after the other: numba compiles one function at a
    time in a process, and processes compiling into one cache take turns (its lock)."""
    import time

    from surgopt.compose import variants
    from surgopt.errors import UsageError
    from surgopt.runner import warm_up
    from surgopt.studies import STUDIES, get_study

    set_verbosity(verbose)
    with guard():
        names = studies or list(STUDIES)
        unknown = [n for n in names if n not in STUDIES]
        if unknown:
            raise UsageError(f"warm: {unknown[0]!r} is not a study (one of: {', '.join(STUDIES)})")
        console = wide_console()
        rows, t0 = [], time.perf_counter()
        for name in names:
            study = get_study(name)
            for overrides in ((), *study.warm_variants):
                (v,) = variants(study, None, list(overrides))
                label = " ".join(overrides) or "embedded default"
                console.print(f"{name}: {label} ...", highlight=False)
                took, compiled = warm_up(study, v.config, say=lambda m: console.print(f"  {m}", highlight=False))
                rows.append([name, label, "compiled" if compiled else "loaded", f"{took:.1f}"])
        print_table(console, f"kernels ready in {time.perf_counter() - t0:.0f} s", ["study", "config", "kernels", "s"],
                    rows)


# the commands that read the store (imported last: they register on ``app``)
from surgopt import cli_results  # noqa: E402,F401


def _reflow_helps() -> None:
    """Every command's docstring as paragraphs of single lines: Rich keeps the source's line breaks, which broke
    the top-level help's lines mid-sentence ("or before / starting several runs")."""
    for info in app.registered_commands:
        if info.help is None and info.callback is not None and info.callback.__doc__:
            info.help = _reflow(info.callback.__doc__)


_reflow_helps()


def main() -> None:
    """The CLI with every stop signal handled (``surgopt.__main__.main`` installs the handlers before it
    imports this module)."""
    from surgopt import interrupts

    interrupts.install()
    run()


def run() -> None:
    """The commands, under handlers already installed: a stop at whatever instant it lands (parsing,
    computing, the closing report, shutting down) ends in one line with its exit code."""
    from surgopt import interrupts

    try:
        from surgopt.hits import answered

        if answered(sys.argv[1:]):  # a recorded plain command line whose run checks out: its report, nothing loaded
            sys.exit(0)
        app(prog_name="surgopt")  # ends in SystemExit; a stop outside a command's guard is typer's silent 130
    except BaseException as exc:  # noqa: BLE001 - any exception a stop caused is the stop
        if interrupts.received() is None and not isinstance(exc, (SystemExit, KeyboardInterrupt)):
            raise
        interrupts.ignore()
        code = exc.code if isinstance(exc, SystemExit) else None
        if interrupts.received() is not None:  # also a stop whose exception a callback swallowed or wrapped
            # now: no wait for worker threads still inside a kernel (their chunks are computed again on resume)
            interrupts.exit_now(interrupts.report(None))
        sys.exit(code)


if __name__ == "__main__":
    sys.exit(main())
