"""Study ``raven-sweep``: Raven IV four-arm port placement and link design (Li et al., ICRA 2011).

config -> geometries (phi_x, phi_y, phi_z, bx, by) -> chunks -> per geometry all
(alpha, beta, Iso_min) designs share the per-node cone angles -> one row per
design: common workspace on the reference plane, zeta = area / circumference
(eq. 33), isotropy sum and cost C (eq. 43). The workspace itself is computed by
``surgopt.kinematics.raven_workspace``; this module holds the config, the rows
and the study's declaration.
"""
from __future__ import annotations

import itertools
import math

import numpy as np

from surgopt.metrics import raven_cost, workspace_compactness
from surgopt.studies.raven_sweep import HELP  # the command's help, read by the CLI without importing this module
from surgopt.studies import Estimate, Flag, Study, Summary, figures_in, html_views_in, peak_bytes
from surgopt.studies.raven_sweep.config import (  # noqa: F401
    PARAM_RANGES,
    PARAMS,
    Config,
    Geometry,
    ParamSpec,
    RavenSweepConfig,
    Refine,
    Span,
    Sweep,
    values,
)
from surgopt.plans.search import SearchPlan, objectives_of, optimiser_of

NAME = "raven-sweep"
CONFIG_HELP = ("TOML or YAML config. Without it: the paper's Table II sweep (250,000 designs: alpha, beta "
             "5-90 deg step 20; phi +-20 deg step 10; bx, by 50-200 mm step 50; Iso_min 0.1-0.9 step 0.2).")
#: raven-4: the half-plane evaluation of mirror-symmetric layouts (rows move <= 2e-14); raven-5: a node at
#: exactly d4 = d4_max is inside (Table I's insertion range is closed), n and the Iso sums of some designs grow
KERNEL_VERSION = "raven-5"
DEFAULT_CONFIG = "raven_table2.toml"
#: Cost model for choosing chunks: ~5 ns per plane node and design on one core (docs/performance.md).
NS_PER_NODE_DESIGN = 5.0
OBJECTIVE = "cost"
KEY_COLUMNS = ("design_id", "source")
#: The optimum of the paper's Table II (C_max = 526.3).
PAPER_OPTIMUM = dict(alpha_deg=85.0, beta_deg=65.0, phi_x_deg=20.0, phi_y_deg=10.0, phi_z_deg=-20.0,
                     bx_mm=100.0, by_mm=50.0, iso_min=0.5)


# ---------------------------------------------------------------------------
# config -> the workspace driver's inputs
# ---------------------------------------------------------------------------


def arm_layout(geo: Geometry):
    """The workspace driver's ``ArmLayout`` for this geometry."""
    from surgopt.kinematics.raven_workspace import ArmLayout

    return ArmLayout(geo.n_arms, None if geo.ports_mm is None else tuple(tuple(p) for p in geo.ports_mm),
                     None if geo.left_arms is None else tuple(geo.left_arms), geo.shoulder_tilt_deg,
                     geo.shoulder_tilt_toward, geo.mirror_left_phi, geo.phi_order, geo.mirror_plane,
                     geo.theta1_zero_toward)


def plane(geo: Geometry):
    """The kernels' ``PlaneGrid`` for this geometry."""
    from surgopt.kinematics.raven_plane import PlaneGrid

    return PlaneGrid(geo.depth_mm, geo.step_mm, geo.d4_max_mm)


GEOMETRY_PARAMS = ("phi_x_deg", "phi_y_deg", "phi_z_deg", "bx_mm", "by_mm")


def geometry_axes(cfg: RavenSweepConfig) -> list[list[float]]:
    """The values of each geometry parameter (phi_x, phi_y, phi_z, bx, by)."""
    return [values(getattr(cfg.sweep, p)) for p in GEOMETRY_PARAMS]


def n_geometries(cfg: RavenSweepConfig) -> int:
    return math.prod(len(v) for v in geometry_axes(cfg))


def geometries(cfg: RavenSweepConfig, start: int, stop: int) -> list[tuple[float, float, float, float, float]]:
    """Geometries start..stop-1 of the sweep in ``itertools.product`` order, without listing the others
    (a sweep can hold far more geometries than fit in memory as Python tuples)."""
    axes = geometry_axes(cfg)
    idx = np.unravel_index(np.arange(start, min(stop, n_geometries(cfg))), [len(v) for v in axes])
    return list(zip(*[[axis[k] for k in ks] for axis, ks in zip(axes, idx)]))


def geometry_grid(cfg: RavenSweepConfig) -> list[tuple[float, float, float, float, float]]:
    """Every (phi_x, phi_y, phi_z, bx, by) of the sweep, in a fixed order."""
    return geometries(cfg, 0, n_geometries(cfg))


def evaluate(cfg: RavenSweepConfig, geometries, alphas_deg, betas_deg, isos) -> np.ndarray:
    """Metrics (G*A*B*I, 6) of every design of these geometries (``evaluate_many``)."""
    from surgopt.kinematics.raven_workspace import evaluate_many

    geo = cfg.geometry
    return evaluate_many(arm_layout(geo), plane(geo), geo.theta2_range_deg, geometries, alphas_deg, betas_deg, isos,
                         theta1_range_deg=geo.theta1_range_deg)


def design_fields(cfg: RavenSweepConfig, params: dict):
    """xs, ys, ports, per-arm and common margins of one design (``raven_workspace.design_fields``)."""
    from surgopt.kinematics.raven_workspace import design_fields as workspace_fields

    geo = cfg.geometry
    g = tuple(params[p] for p in ("phi_x_deg", "phi_y_deg", "phi_z_deg", "bx_mm", "by_mm"))
    return workspace_fields(arm_layout(geo), plane(geo), geo.theta2_range_deg, g, params["alpha_deg"],
                             params["beta_deg"], params["iso_min"], theta1_range_deg=geo.theta1_range_deg)


def _rows(params: np.ndarray, metrics: np.ndarray, step_mm: float, ids: np.ndarray, source: str) -> dict:
    area_cm2 = metrics[:, 0] / 100.0
    per_cm = metrics[:, 1] / 10.0
    zeta = workspace_compactness(area_cm2, per_cm)
    n_pts = metrics[:, 2]
    iso_sum = metrics[:, 3]
    cols = {"design_id": ids.astype(np.int64)}
    for i, p in enumerate(PARAMS):
        cols[p] = params[:, i].copy()
    cols.update({
        "area_cm2": area_cm2, "perimeter_cm": per_cm, "zeta_cm": zeta, "iso_sum": iso_sum,
        "iso_mean": np.where(n_pts > 0, iso_sum / np.where(n_pts > 0, n_pts, 1.0), 0.0),
        "iso_area_cm2": iso_sum * step_mm * step_mm / 100.0,
        "iso_min_actual": metrics[:, 4], "n_points": n_pts.astype(np.int64),
        "cost": raven_cost(zeta, iso_sum, params[:, 7], np.radians(params[:, 0]), np.radians(params[:, 1])),
        "source": [source] * len(ids),
    })
    return cols


# ---------------------------------------------------------------------------
# tasks
# ---------------------------------------------------------------------------


def schema():
    import pyarrow as pa

    return pa.schema(
        [pa.field("design_id", pa.int64())] + [pa.field(p, pa.float64()) for p in PARAMS] +
        [pa.field(c, pa.float64()) for c in ("area_cm2", "perimeter_cm", "zeta_cm", "iso_sum", "iso_mean",
                                             "iso_area_cm2", "iso_min_actual")] +
        [pa.field("n_points", pa.int64()), pa.field("cost", pa.float64(), metadata={"eq": "43"}),
         pa.field("source", pa.string())])


def auto_chunk(cfg: RavenSweepConfig) -> int:
    """Geometries per task: about TARGET_TASK_S (1 s) of single-core work, and at least 32 tasks."""
    from surgopt.studies import chunk_for_seconds

    sw = cfg.sweep
    designs = len(values(sw.alpha_deg)) * len(values(sw.beta_deg)) * len(values(sw.iso_min))
    return chunk_for_seconds(n_geometries(cfg), _plane_nodes(cfg.geometry) * designs * NS_PER_NODE_DESIGN * 1e-9)


def _plane_nodes(geo: Geometry) -> float:
    """Nodes of the plane grid one geometry evaluates (the square around one arm's reach; its half
    x >= 0 when the arms are their own mirror image, ``mirror_symmetric``)."""
    reach = math.sqrt(geo.d4_max_mm ** 2 - geo.depth_mm ** 2)
    return (2 * reach / geo.step_mm) ** 2 * (0.5 if mirrored_layout(geo) else 1.0)


def mirrored_layout(geo: Geometry) -> bool:
    """Whether the kernel evaluates half the plane: the arms mirror themselves in x = 0
    (``raven_plane.mirror_symmetric``, a property of the layout, checked on one placement)."""
    from surgopt.kinematics.raven_plane import mirror_symmetric
    from surgopt.kinematics.raven_workspace import arm_frames, left_arms

    layout = arm_layout(geo)
    ports, axes, zero_axes = arm_frames(layout, 10.0, 5.0, -5.0, 100.0, 50.0)
    return bool(mirror_symmetric.py_func(ports, axes, zero_axes, left_arms(layout), theta1_limited(geo)))


#: Time model of the estimate, fitted to single-core runs of Table II and a 12-design sweep (within
#: 10% of both; docs/performance.md): per distinct geometry, NS_PER_NODE_ARM for the node bounds of
#: each arm, plus NS_PER_NODE_DESIGN_EST for each design (bounding boxes skip most of the plane).
NS_PER_NODE_ARM = 5.4
NS_PER_NODE_DESIGN_EST = 0.35
#: A limited theta1 adds, per distinct geometry, its fields (NS_PER_NODE_ARM_THETA1 per node and arm) and
#: its test for each (alpha, beta) (NS_PER_NODE_PAIR_ARM_THETA1), and makes every geometry distinct;
#: fitted to Table II at [0, 90] deg (1.9-2.2 s on 2 threads; docs/performance.md).
NS_PER_NODE_ARM_THETA1 = 1.0
NS_PER_NODE_PAIR_ARM_THETA1 = 0.1
#: Up to this many geometries the estimate counts the distinct ones (identical ports and axes are
#: evaluated once); beyond it every geometry counts, an upper bound.
DISTINCT_COUNT_MAX = 20_000


def theta1_limited(geo: Geometry) -> bool:
    """Whether the shoulder range limits anything (a range of 360 deg or more is no limit)."""
    r = geo.theta1_range_deg
    return r is not None and r[1] - r[0] < 360


def distinct_geometries(cfg: RavenSweepConfig) -> int:
    """How many geometries of the sweep place the arms differently (the rest share an evaluation)."""
    n = n_geometries(cfg)
    if n > DISTINCT_COUNT_MAX:
        return n
    from surgopt.kinematics.raven_workspace import arm_frames

    layout = arm_layout(cfg.geometry)
    limited = theta1_limited(cfg.geometry)
    seen = set()
    for g in geometries(cfg, 0, n):
        ports, axes, zero_axes = arm_frames(layout, *g)
        seen.add((ports + 0.0).tobytes() + (axes + 0.0).tobytes() + ((zero_axes + 0.0).tobytes() if limited else b""))
    return len(seen)


optimiser = optimiser_of  # the [search] optimiser of a config, or None (the grid)


def search_plan(cfg: RavenSweepConfig) -> SearchPlan | None:
    """An optimiser's space: each swept parameter's {start, stop} as continuous bounds, lists categorical."""
    spec = optimiser(cfg)
    if spec is None:
        return None
    space = {}
    for p in PARAMS:
        s = getattr(cfg.sweep, p)
        space[p] = (float(s.start), float(s.stop)) if isinstance(s, Span) else [float(v) for v in s]
    return SearchPlan(spec, space, objectives_of(spec, OBJECTIVE))


def estimate(cfg: RavenSweepConfig) -> Estimate:
    """Distinct geometries x (node bounds + designs) on the plane grid; a row is ~160 bytes; memo 64 MB."""
    sw, nodes = cfg.sweep, _plane_nodes(cfg.geometry)
    spec = optimiser(cfg)
    if spec is not None:
        n = spec.trials
        return Estimate(n, f"{spec.method} trials", n,
                        n * nodes * (cfg.geometry.n_arms * NS_PER_NODE_ARM + NS_PER_NODE_DESIGN_EST) * 1e-9,
                        peak_bytes(n, 160))
    per = len(values(sw.alpha_deg)) * len(values(sw.beta_deg)) * len(values(sw.iso_min))
    g = n_geometries(cfg)
    ns_node = cfg.geometry.n_arms * NS_PER_NODE_ARM + per * NS_PER_NODE_DESIGN_EST
    if theta1_limited(cfg.geometry):
        pairs = len(values(sw.alpha_deg)) * len(values(sw.beta_deg))
        ns_node += cfg.geometry.n_arms * (NS_PER_NODE_ARM_THETA1 + pairs * NS_PER_NODE_PAIR_ARM_THETA1)
    seconds = distinct_geometries(cfg) * nodes * ns_node
    return Estimate(g * per, "designs", g * per, seconds * 1e-9, peak_bytes(g * per, 160, working_bytes=64 * 2 ** 20))


def n_tasks(cfg: RavenSweepConfig, chunk: int) -> int:
    """Chunks of the sweep's geometries."""
    return max(1, math.ceil(n_geometries(cfg) / chunk))


def warm_up(cfg: RavenSweepConfig) -> None:
    small = cfg.model_copy(update={"geometry": cfg.geometry.model_copy(update={"step_mm": 20.0})})
    evaluate(small, [(0.0, 0.0, 0.0, 100.0, 50.0)], [45.0], [45.0], [0.5])


def evaluate_designs(cfg: RavenSweepConfig, x: np.ndarray, ids: np.ndarray, source: str) -> dict:
    """Rows of any designs (rows of ``x`` in PARAMS order), one by one (a plan's batch: ids are its trial numbers)."""
    x = np.asarray(x, dtype=np.float64).reshape(-1, len(PARAMS))
    metrics = np.vstack([evaluate(cfg, [tuple(d[2:7])], [d[0]], [d[1]], [d[7]]) for d in x])
    return _rows(x, metrics, cfg.geometry.step_mm, np.asarray(ids), source)


def compute_task(cfg: RavenSweepConfig, chunk: int, index: int) -> dict:
    """Rows of the sweep's geometries [index*chunk, (index+1)*chunk), each with every (alpha, beta, Iso_min)."""
    sw = cfg.sweep
    al, be, iso = values(sw.alpha_deg), values(sw.beta_deg), values(sw.iso_min)
    per_geo = len(al) * len(be) * len(iso)
    g0, g1 = index * chunk, min(n_geometries(cfg), (index + 1) * chunk)
    geos = geometries(cfg, g0, g1)
    params = []
    design = np.array(list(itertools.product(al, be, iso)))  # (per_geo, 3)
    for g in geos:
        p = np.empty((per_geo, 8))
        p[:, 0], p[:, 1], p[:, 7] = design[:, 0], design[:, 1], design[:, 2]
        p[:, 2:7] = g
        params.append(p)
    metrics = evaluate(cfg, geos, al, be, iso)
    ids = np.arange(g0 * per_geo, g1 * per_geo)
    return _rows(np.vstack(params), metrics, cfg.geometry.step_mm, ids, "grid")


# ---------------------------------------------------------------------------
# refine: a compass search from the grid's best designs
# ---------------------------------------------------------------------------


def sweep_bounds(cfg: RavenSweepConfig) -> list[tuple[float, float]]:
    """(lowest, highest) value of each parameter in the sweep, in PARAMS order."""
    return [(min(values(getattr(cfg.sweep, p))), max(values(getattr(cfg.sweep, p)))) for p in PARAMS]


def design_box(cfg: RavenSweepConfig) -> list:
    """The sweep's box: each parameter with more than one value (a span's start and stop, a list's extremes)."""
    from surgopt.studies import Edge

    out = []
    for p, (lo, hi) in zip(PARAMS, sweep_bounds(cfg)):
        spec = getattr(cfg.sweep, p)
        fields = (f"sweep.{p}.start", f"sweep.{p}.stop") if isinstance(spec, Span) else (f"sweep.{p}", f"sweep.{p}")
        out.append(Edge(p, lo, hi, *fields))
    return out


def refine_space(cfg: RavenSweepConfig):
    """The compass search's space (the refine plan): PARAMS, the sweep's bounds, and steps of half the grid
    spacing (1/8 of the range for listed values, 0 for a single value)."""
    bounds = sweep_bounds(cfg)
    steps = []
    for p, (lo, hi) in zip(PARAMS, bounds):
        spec = getattr(cfg.sweep, p)
        steps.append(spec.step / 2 if isinstance(spec, Span) else (hi - lo) / 8 or 0.0)
    return list(PARAMS), bounds, steps


# ---------------------------------------------------------------------------
# summary
# ---------------------------------------------------------------------------


def _is_paper_optimum(t):
    mask = np.ones(t.num_rows, bool)
    for p, v in PAPER_OPTIMUM.items():
        mask &= np.abs(t[p].to_numpy() - v) < 1e-9
    return mask


def paper_optimum_rank(parts):
    """(rank by cost, row) of the Table II optimum in a grid run (``Parts`` or a table), or None.

    1 + the designs that cost more; without a common workspace (cost 0) it ranks last, not tied first
    with every other empty design."""
    from surgopt.parts import Parts

    parts = parts if isinstance(parts, Parts) else Parts.of_table(parts)
    hit = parts.filter(_is_paper_optimum)
    if hit.num_rows == 0:
        return None
    c = hit["cost"][0].as_py()
    if c > 0:
        rank = parts.count(lambda t: t["cost"].to_numpy() > c, columns=["cost"]) + 1
    else:
        rank = parts.count(lambda t: np.ones(t.num_rows, bool), columns=["cost"])
    return rank, {k: hit[k][0].as_py() for k in hit.column_names}


def summary(parts) -> Summary:
    """Designs with a common workspace, the best design by cost, the paper optimum's rank, the top 10
    (``parts``: a ``surgopt.parts.Parts``, read part by part)."""
    with_ws = parts.count(lambda t: t["n_points"].to_numpy() > 0, columns=["n_points"])
    headline = {"designs": parts.num_rows, "with_common_workspace": with_ws}
    top = parts.top("cost", 10)
    if top.num_rows:
        headline.update({f"best_{p}": top[p][0].as_py() for p in PARAMS})
        headline.update({"best_cost": top["cost"][0].as_py(), "best_zeta_cm": top["zeta_cm"][0].as_py()})
    r = paper_optimum_rank(parts)
    if r is not None:
        headline.update({"paper_optimum_rank": r[0], "paper_optimum_cost": r[1]["cost"]})
    cols = list(PARAMS) + ["zeta_cm", "area_cm2", "iso_mean", "cost"]
    rows = [[f"{top[c][i].as_py():.4g}" for c in cols] for i in range(top.num_rows)]
    return Summary(headline, {"with_common_workspace": with_ws, "without": parts.num_rows - with_ws},
                   [("top designs by cost C (eq. 43)", cols, rows)])


def feasible_mask(table):
    return table["n_points"].to_numpy() > 0


STUDY = Study(
    html_views=html_views_in("surgopt.studies.raven_sweep.html"),
    name=NAME, kernel_version=KERNEL_VERSION, config_model=RavenSweepConfig, default_config=DEFAULT_CONFIG,
    help=HELP, config_help=CONFIG_HELP, schema=schema, key_columns=KEY_COLUMNS, objective=OBJECTIVE,
    auto_chunk=auto_chunk, n_tasks=n_tasks, warm_up=warm_up, compute_task=compute_task, summary=summary,
    feasible_mask=feasible_mask, feasible_columns=("n_points",), figures=figures_in("surgopt.studies.raven_sweep.figures"), estimate=estimate, search_plan=search_plan,
    evaluate=evaluate_designs, refine_space=refine_space, design_box=design_box,
    flags=(Flag("--refine", "After the run, a compass search from its top refine.top_k designs inside the sweep's "
                            "bounds; stored as a second run that records the first's key.",
                follow_up="refine", follow_up_suffix="+refine"),))
