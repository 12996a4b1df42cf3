"""Studies: each one declared object (``Study``) that turns a config into tasks and tasks into rows.

The orchestration (``runner``, ``store``, ``results``, ``report``, ``cli``) reads a study only
through this protocol and knows no study by name; the registry below is the one place that lists
them. A new study is a folder ``surgopt/studies/<study>/`` whose ``study.py`` defines ``STUDY = Study(...)``
(beside its ``config.py``, ``figures.py`` and ``html.py``), an embedded default config in ``surgopt/defaults``,
and one line in ``STUDIES`` (docs/architecture.md, "Adding a study").
"""
from __future__ import annotations

import importlib
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping

#: Study name (the CLI command) -> module defining ``STUDY``.
STUDIES = {"rcm-grid": "surgopt.studies.rcm_grid.study", "rcm-track": "surgopt.studies.rcm_track.study",
           "raven-sweep": "surgopt.studies.raven_sweep.study", "suture-sim": "surgopt.studies.suture_sim.study",
           "port-place": "surgopt.studies.port_place.study"}


@dataclass(frozen=True)
class Summary:
    """What a study says about a table, computed once: the closing report, ``summarize`` and ``check``
    all read it.

    ``headline``: the run's headline numbers (snake_case keys, units in the names);
    ``feasibility``: counts of feasible and infeasible designs (or runs);
    ``tables``: study-specific tables as (title, header, rows).
    """

    headline: dict[str, Any]
    feasibility: dict[str, int]
    tables: list[tuple[str, list[str], list[list]]] = field(default_factory=list)
    #: whether the closing report added to the run's own summary for the config the user gave
    #: (``Study.config_report``): shown, never kept beside the run
    added: bool = False

    def with_added(self, added: tuple[dict, list] | None) -> "Summary":
        """This summary with ``Study.config_report``'s (headline items, tables) added, the tables first; itself
        when there is nothing to add."""
        if added is None:
            return self
        return Summary({**self.headline, **added[0]}, self.feasibility, [*added[1], *self.tables], added=True)


@dataclass(frozen=True)
class Estimate:
    """What a config implies before it runs: ``items`` (designs, candidates or time steps, named by
    ``what``), rows stored, single-core seconds and the parent's peak memory in bytes; ``smaller``: what a
    refusal suggests besides lifting the budget."""

    items: int
    what: str
    rows: int
    seconds_one_core: float
    peak_bytes: int
    smaller: str = "make it smaller"  # how to make the config cheaper, said when a budget refuses it
    #: rows the store will likely hold, when fewer than ``rows`` (an upper bound): port-place's feasible rows only
    stored_rows: int | None = None
    #: the parent's peak were every row stored (``peak_bytes`` then allows for the share ``stored_rows`` assumes, and
    #: more): what the dry run shows beside it; None when ``peak_bytes`` is already that
    peak_bytes_bound: int | None = None


#: Resident memory of a study process before any work: Python, numpy, numba, pyarrow (measured: 270 MB).
BASE_PROCESS_BYTES = 280 * 2 ** 20
#: The parent streams the table: it holds one column of it (8 bytes a row, for summarize's statistics)
#: and a few chunks in flight (at least 32 chunks, 2 per worker in flight: ~1/8 of the rows' bytes).
IN_FLIGHT_SHARE = 1 / 8


def peak_bytes(rows: int, bytes_per_row: int, working_bytes: int = 0) -> int:
    """The parent's peak memory for a run of ``rows`` rows plus other working memory (docs/reliability.md)."""
    return int(BASE_PROCESS_BYTES + rows * (8 + bytes_per_row * IN_FLIGHT_SHARE) + working_bytes)


@dataclass(frozen=True)
class Flag:
    """A command-line flag of one study: boolean, or with a value when ``metavar`` is set.

    ``config_update`` is merged into the config before the run (``--cull``: ``{"search": "cull"}``);
    ``value_update(value)`` gives the update of a flag with a value (``--robot ur5e``);
    ``follow_up`` names a plan (``surgopt.plans``) that explores the same config after the run, from its
    rows, stored as a second run named ``<config name><follow_up_suffix>`` (``--refine``);
    ``expand(cfg)`` turns one config into several (label, config), each its own run, reported side by side as a
    --multirun is (``--branches``); ``implied(cfg)``: a reason the expansion applies without the flag (rcm-grid:
    an unseeded URDF or DH arm runs once per IK branch), or None.
    """

    option: str
    help: str
    config_update: Mapping[str, Any] | None = None
    follow_up: str | None = None
    follow_up_suffix: str = ""
    metavar: str | None = None
    value_update: Callable[[str], Mapping[str, Any]] | None = None
    expand: Callable[[Any], list] | None = None
    implied: Callable[[Any], str | None] | None = None

    def update(self, value) -> Mapping[str, Any]:
        """The config update this flag makes when given (``value``: True, or the flag's value)."""
        if self.value_update is not None:
            return self.value_update(value)
        return self.config_update or {}

    @property
    def dest(self) -> str:
        return self.option.lstrip("-").replace("-", "_")


@dataclass(frozen=True)
class Study:
    """One study: config model -> tasks -> rows (a dict of numpy columns per task) -> summary, figures.

    ``compute_task(cfg, chunk, index)`` (the study's grid, chunk by chunk) and ``evaluate`` (any designs) must be
    pure functions of their arguments (they run in threads, worker processes or on a cluster); how the design
    space is explored is a plan (``surgopt.plans``), not the study's; ``warm_up(cfg)`` compiles the kernels in the parent first.
    ``objective`` ranks designs (descending) in ``summarize``; None compares runs side by side.
    ``figures(cfg, table, out_dir, design_id)`` writes PNG files and returns their paths.
    ``estimate(cfg)`` says what the config costs before anything runs (an ``Estimate``).
    """

    name: str
    kernel_version: str
    config_model: type
    default_config: str
    help: str
    config_help: str
    schema: Callable[[], Any]
    key_columns: tuple[str, ...]
    objective: str | None
    auto_chunk: Callable[[Any], int]
    n_tasks: Callable[[Any, int], int]
    warm_up: Callable[[Any], None]
    compute_task: Callable[[Any, int, int], dict]
    summary: Callable[[Any], Summary]
    feasible_mask: Callable[[Any], Any]
    figures: Callable[[Any, Any, Path, int | None], list[Path]]
    flags: tuple[Flag, ...] = ()
    #: the columns ``feasible_mask`` reads, when it reads a table by these names alone: a summary then reads those
    #: and its objective, not every column (``Parts.scan``); None: any
    feasible_columns: tuple[str, ...] | None = None
    #: ``preflight(cfg)``: a check that needs the kernels (port-place: a target no candidate port reaches), run in
    #: the parent after the kernels load and before anything is written; a ValueError "field: why" refuses the config
    preflight: Callable[[Any], None] | None = None
    #: ``top_columns(config as stored)``: the columns ``summarize``'s top table shows when --columns is not given
    #: (None: every column); a study of dozens of columns names the few a reader compares layouts by
    top_columns: Callable[[Any], list[str]] | None = None
    #: ``figure_columns(config as stored)``: the only columns the grid's figures read (None: every column); a run
    #: of millions of rows then plots in the memory of a few columns
    figure_columns: Callable[[Any], list[str]] | None = None
    chunked: bool = True  # False: one task per run, no --chunk-size
    estimate: Callable[[Any], Estimate] | None = None  # work and memory, checked before a run starts
    #: The objective a person reads a search by, when the optimiser's is a penalised stand-in for it: (column,
    #: "minimize" | "maximize"), over the feasible trials (port-place: the cost, not the score); None: the plan's
    reported_objective: tuple[str, str] | None = None
    #: ``surgopt export KEY --design ID --format NAME``: a study's own formats of one design's row, NAME ->
    #: ``write(cfg, row) -> text`` (``cfg`` the run's validated config; port-place: "dvrk", the layout's set-up for
    #: the robot)
    exports: Mapping[str, Callable[[Any, dict], str]] = field(default_factory=dict)
    #: The sections of the run's HTML page (``surgopt report``): ``html_views(run, cfg, parts)`` ->
    #: [``studies.page.View``] (``cfg``: the run's validated config)
    html_views: Callable[[Any, Any, Any], list] | None = None
    #: ``config_report(cfg, parts)``: what the closing report adds for the config the user gave beyond the run's
    #: own summary, from fields left out of the run's key (port-place: a surgeon's own layout scored against the
    #: stored run, so that another layout reuses the run's rows): (headline items, tables), or None for nothing.
    #: Never kept beside the run; a command whose report it adds to is not answered from ``_hits``.
    config_report: Callable[[Any, Any], tuple[dict, list] | None] | None = None
    #: Override sets (KEY=VALUE strings) whose kernels the embedded default does not compile: ``surgopt warm``
    #: compiles them too (another metric, a generic arm, a serial arm in port-place)
    warm_variants: tuple[tuple[str, ...], ...] = ()
    #: What ``warm_up(cfg)`` builds besides loading the kernels, for the word the runner says while it runs (e.g.
    #: "the per-port tables"); "": the kernels alone
    warm_up_builds: str = ""
    search_plan: Callable[[Any], Any] | None = None  # a SearchPlan when the config asks for an optimiser
    #: ``evaluate(cfg, x, ids, source)``: rows of any designs (rows of x in ``search_plan``'s dimension order),
    #: what the optimiser and refine plans evaluate; None: the study is explored by its grid alone
    evaluate: Callable[[Any, Any, Any, str], dict] | None = None
    #: ``refine_space(cfg)``: (dimension names, bounds, compass steps) for the refine plan
    refine_space: Callable[[Any], Any] | None = None
    #: ``design_box(cfg)``: the box the config explores, as ``Edge``s: an optimum on one is reported
    design_box: Callable[[Any], list] | None = None
    #: ``cull(cfg)``: the rows of the study's exact argmax by culling (the cull plan), if it has one
    cull: Callable[[Any], dict] | None = None
    #: ``advice(cfg)``: lines the CLI prints before a run (and --dry-run shows): a set-up that runs but is likely
    #: not what the user meant (a tool pointing sideways)
    advice: Callable[[Any], list[str]] | None = None
    #: this study runs another study's configs plus a section of its own (rcm-track: rcm-grid's + [track]);
    #: a config file without that section is the other study's when a command must tell them apart
    extends: str | None = None
    config_section: str | None = None
    #: ``design_identity(config as stored)``: (columns that identify a design across runs whose enumerations
    #: differ, rounded to ``MATCH_DECIMALS`` when joined; columns that only index the run's own enumeration).
    #: ``diff`` joins two runs on the former and leaves the latter out of its changes (port-place: each arm's
    #: port coordinates; design_id and the site indices). None: the key columns identify a design.
    design_identity: Callable[[Any], tuple[tuple[str, ...], tuple[str, ...]]] | None = None

    def schema_for(self, config=None):
        """The schema of a run's rows: ``schema(config)`` when the study's columns depend on its config (rcm-grid's
        singular values are named for its metric), ``schema()`` otherwise. ``config``: validated, or as stored."""
        import inspect

        return self.schema(config) if inspect.signature(self.schema).parameters else self.schema()


@dataclass(frozen=True)
class Edge:
    """One dimension of the box a config explores: its row ``column``, bounds and the config fields that set them."""

    column: str
    low: float
    high: float
    low_field: str
    high_field: str


def figures_in(module: str) -> Callable:
    """``Study.figures`` for ``surgopt.studies.plotting.<module>``, imported on the first call (so that
    matplotlib loads only when a figure is drawn)."""

    def figures(cfg, table, out_dir: Path, design_id: int | None = None) -> list[Path]:
        return importlib.import_module(module).figures(cfg, table, out_dir, design_id)

    return figures


def summary_in(module: str) -> Callable:
    """``Study.summary`` for the ``summary`` of the module of that dotted name (a study's closing report),
    imported on the first call."""

    def summary(parts) -> "Summary":
        return importlib.import_module(module).summary(parts)

    return summary


def html_views_in(module: str) -> Callable:
    """``Study.html_views`` for the ``views`` of the module of that dotted name (a study's ``html.py``), imported
    on the first call."""

    def views(run, cfg, parts) -> list:
        return importlib.import_module(module).views(run, cfg, parts)

    return views


def get_study(name: str) -> Study:
    """The declared study of that name (``KeyError`` for an unknown one)."""
    return importlib.import_module(STUDIES[name]).STUDY


#: Work per task the automatic chunk size aims at (s on one core), and the fewest tasks it makes: with two
#: workers the bar moves about twice a second (issue 38: it stood still for minutes inside long chunks).
TARGET_TASK_S = 1.0
MIN_TASKS = 32


def chunk_for_seconds(n_items: int, seconds_per_item: float) -> int:
    """Items per task for ~TARGET_TASK_S of work each, but at least MIN_TASKS tasks when possible."""
    by_time = max(1, int(TARGET_TASK_S / max(seconds_per_item, 1e-12)))
    by_count = max(1, math.ceil(n_items / MIN_TASKS))
    return min(by_time, by_count)
