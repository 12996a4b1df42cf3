"""Study ``raven-sweep``: Raven IV four-arm port placement and link design (Li et al., ICRA 2011).

config -> geometries (phi_x, phi_y, phi_z, bx, by) -> chunks -> per geometry all
(alpha, beta, Iso_min) designs share the per-node cone angles -> one row per
design: common workspace on the reference plane, zeta = area / circumference
(eq. 33), isotropy sum and cost C (eq. 43).
"""
from __future__ import annotations

import itertools
import math
import threading
from typing import Literal

import numpy as np
from pydantic import Field, model_validator

from surgopt.config import StrictModel
from surgopt.robots import raven_iv

NAME = "raven-sweep"
KERNEL_VERSION = "raven-3"
DEFAULT_CONFIG = "raven_table2.toml"
#: Cost model for choosing chunks: ~5 ns per plane node and design on one core (docs/performance.md).
NS_PER_NODE_DESIGN = 5.0
OBJECTIVE = "cost"
KEY_COLUMNS = ("design_id", "source")
PARAMS = ("alpha_deg", "beta_deg", "phi_x_deg", "phi_y_deg", "phi_z_deg", "bx_mm", "by_mm", "iso_min")
#: The optimum of the paper's Table II (C_max = 526.3).
PAPER_OPTIMUM = dict(alpha_deg=85.0, beta_deg=65.0, phi_x_deg=20.0, phi_y_deg=10.0, phi_z_deg=-20.0,
                     bx_mm=100.0, by_mm=50.0, iso_min=0.5)


class Span(StrictModel):
    """start, start + step, ... up to stop (inclusive when it lands on it)."""

    start: float
    stop: float
    step: float = Field(gt=0)

    @model_validator(mode="after")
    def _ordered(self):
        if self.stop < self.start:
            raise ValueError("stop must be >= start")
        if (self.stop - self.start) / self.step > 10_000:
            raise ValueError("more than 10,000 values")
        return self

    def values(self) -> list[float]:
        n = int(math.floor((self.stop - self.start) / self.step + 1e-9))
        return [round(self.start + i * self.step, 10) for i in range(n + 1)]


ParamSpec = list[float] | Span


def values(spec: ParamSpec) -> list[float]:
    return spec.values() if isinstance(spec, Span) else list(spec)


class Sweep(StrictModel):
    alpha_deg: ParamSpec = Span(start=5, stop=90, step=20)
    beta_deg: ParamSpec = Span(start=5, stop=90, step=20)
    phi_x_deg: ParamSpec = Span(start=-20, stop=20, step=10)
    phi_y_deg: ParamSpec = Span(start=-20, stop=20, step=10)
    phi_z_deg: ParamSpec = Span(start=-20, stop=20, step=10)
    bx_mm: ParamSpec = Span(start=50, stop=200, step=50)
    by_mm: ParamSpec = Span(start=50, stop=200, step=50)
    iso_min: ParamSpec = Span(start=0.1, stop=0.9, step=0.2)

    @model_validator(mode="after")
    def _ranges(self):
        checks = {"alpha_deg": (0, 180), "beta_deg": (0, 180), "phi_x_deg": (-90, 90), "phi_y_deg": (-90, 90),
                  "phi_z_deg": (-180, 180), "bx_mm": (0, 2000), "by_mm": (0, 2000), "iso_min": (0, 1)}
        for name, (lo, hi) in checks.items():
            vs = values(getattr(self, name))
            if not vs:
                raise ValueError(f"{name}: no values")
            if min(vs) < lo or max(vs) > hi or (name in ("alpha_deg", "beta_deg") and min(vs) <= 0):
                raise ValueError(f"{name}: values must lie in [{lo}, {hi}]")
        return self


class Geometry(StrictModel):
    """What the paper leaves to its Fig. 3 (docs/reproduction.md, Raven section)."""

    n_arms: Literal[1, 2, 4] = 4
    ports_mm: list[list[float]] | None = Field(None, description="[[x, y], ...] per arm; overrides bx/by")
    left_arms: list[bool] | None = Field(None, description="mirrored (left) arms; default 1 and 3")
    shoulder_tilt_deg: float = Field(90.0, ge=-90, le=90, description="axis 1 from vertical at phi = 0, outward")
    shoulder_tilt_toward: Literal["x", "y"] = Field(
        "x", description="outward along x (away from the other side) or y (away from the other pair)")
    mirror_left_phi: bool = True
    depth_mm: float = Field(raven_iv.REFERENCE_PLANE_DEPTH_MM, gt=0)
    step_mm: float = Field(2.0, gt=0.05, le=50)
    d4_max_mm: float = Field(raven_iv.D4_RANGE_MM[1], gt=0)
    theta2_range_deg: list[float] = Field(list(raven_iv.THETA2_RANGE_DEG), min_length=2, max_length=2)

    @model_validator(mode="after")
    def _consistent(self):
        if self.d4_max_mm <= self.depth_mm:
            raise ValueError("d4_max_mm must exceed depth_mm or no point is reachable")
        lo, hi = self.theta2_range_deg
        if not 0 <= lo < hi <= 180:
            raise ValueError("theta2_range_deg must satisfy 0 <= lo < hi <= 180")
        for name in ("ports_mm", "left_arms"):
            v = getattr(self, name)
            if v is not None and len(v) != self.n_arms:
                raise ValueError(f"{name} must list {self.n_arms} arms")
        if self.ports_mm is not None and any(len(p) != 2 for p in self.ports_mm):
            raise ValueError("ports_mm entries are [x, y]")
        return self


class Refine(StrictModel):
    top_k: int = Field(5, ge=1, le=100)
    max_evals: int = Field(300, ge=10, le=100_000)
    starts: list[list[float]] | None = Field(None, description="filled by --refine from the grid's top designs")


class RavenSweepConfig(StrictModel):
    sweep: Sweep = Sweep()
    geometry: Geometry = Geometry()
    search: Literal["grid", "refine"] = "grid"
    refine: Refine = Refine()

    @model_validator(mode="after")
    def _ports_fix_bx_by(self):
        if self.geometry.ports_mm is not None:
            for name in ("bx_mm", "by_mm"):
                if len(values(getattr(self.sweep, name))) > 1:
                    raise ValueError(f"sweep.{name} has several values, but geometry.ports_mm fixes the ports "
                                     f"(bx_mm, by_mm are not used then): give one value")
        return self


Config = RavenSweepConfig


# ---------------------------------------------------------------------------
# geometry
# ---------------------------------------------------------------------------


def _cos_sin_deg(deg: float) -> tuple[float, float]:
    """cos and sin of an angle in degrees, exact at multiples of 90 (cos 90 deg is 0, not 6e-17)."""
    if deg % 90 == 0:
        return ((1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0))[int(deg // 90) % 4]
    return math.cos(math.radians(deg)), math.sin(math.radians(deg))


def _rot(axis: int, deg: float) -> np.ndarray:
    c, s = _cos_sin_deg(deg)
    if axis == 0:
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    if axis == 1:
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def arms(geo: Geometry, phi_x: float, phi_y: float, phi_z: float, bx: float, by: float):
    """Ports (n, 3) and shoulder-axis directions (n, 3) in the world frame.

    Ports: 4 arms at (-bx/2, +by/2), (+bx/2, +by/2), (-bx/2, -by/2), (+bx/2, -by/2)
    (arms 1-4, left arms 1 and 3), 2 arms at (-+bx/2, 0), 1 arm at 0.
    Axis 1 at phi = 0: vertical (out of the patient), tilted outward by
    ``shoulder_tilt_deg`` along x (away from the other side's arms) or along y
    (away from the other pair), per ``shoulder_tilt_toward``; then R = Rz(phi_z) Ry(phi_y) Rx(phi_x) about the
    port, with phi_y, phi_z negated for left arms when ``mirror_left_phi``
    (the mirror image of a right arm's rotation).
    """
    if geo.ports_mm is not None:
        ports = [(p[0], p[1]) for p in geo.ports_mm]
    elif geo.n_arms == 4:
        ports = [(-bx / 2, by / 2), (bx / 2, by / 2), (-bx / 2, -by / 2), (bx / 2, -by / 2)]
    elif geo.n_arms == 2:
        ports = [(-bx / 2, 0.0), (bx / 2, 0.0)]
    else:
        ports = [(0.0, 0.0)]
    left = geo.left_arms if geo.left_arms is not None else [i % 2 == 0 for i in range(geo.n_arms)]
    P = np.array([[x, y, 0.0] for x, y in ports])
    A = np.empty((geo.n_arms, 3))
    ct, st = _cos_sin_deg(geo.shoulder_tilt_deg)
    for i, is_left in enumerate(left):
        if geo.shoulder_tilt_toward == "x":
            out = -1.0 if is_left else 1.0
            u0 = np.array([out * st, 0.0, ct])
        else:
            out = 1.0 if P[i, 1] >= 0 else -1.0
            u0 = np.array([0.0, out * st, ct])
        m = -1.0 if (is_left and geo.mirror_left_phi) else 1.0
        R = _rot(2, m * phi_z) @ _rot(1, m * phi_y) @ _rot(0, phi_x)
        A[i] = R @ u0
    return P, A


def plane_grid(geo: Geometry, ports: np.ndarray):
    """Node coordinates covering every point all arms can reach (|X - port| <= d4_max)."""
    from surgopt.kinematics.raven import plane_grid as kernel_plane_grid

    return kernel_plane_grid(np.ascontiguousarray(ports, dtype=np.float64), float(geo.depth_mm),
                             float(geo.d4_max_mm), float(geo.step_mm))


def geometry_grid(cfg: RavenSweepConfig) -> list[tuple[float, float, float, float, float]]:
    sw = cfg.sweep
    return list(itertools.product(values(sw.phi_x_deg), values(sw.phi_y_deg), values(sw.phi_z_deg),
                                  values(sw.bx_mm), values(sw.by_mm)))


def psi_intervals(cfg: RavenSweepConfig, alphas, betas, isos):
    """Cone-angle interval per (alpha, beta, Iso_min) from the theta2 range narrowed by Iso_min."""
    from surgopt.kinematics.raven import cone_angle, theta2_interval

    lo2, hi2 = (math.radians(v) for v in cfg.geometry.theta2_range_deg)
    shape = (len(alphas), len(betas), len(isos))
    plo, phi_, has = np.zeros(shape), np.zeros(shape), np.zeros(shape, bool)
    for (i, a), (j, b), (k, m) in itertools.product(enumerate(alphas), enumerate(betas), enumerate(isos)):
        t_lo, t_hi, ok = theta2_interval(a, b, m, lo2, hi2)
        plo[i, j, k], phi_[i, j, k], has[i, j, k] = cone_angle(t_lo, a, b), cone_angle(t_hi, a, b), ok
    return plo, phi_, has


def evaluate(cfg: RavenSweepConfig, geometry, alphas_deg, betas_deg, isos, intervals=None):
    """Metrics (A*B*I, 6) of every design of one geometry (see ``evaluate_designs``)."""
    return evaluate_many(cfg, [geometry], alphas_deg, betas_deg, isos, intervals)


#: Metrics of geometries already evaluated in this process, keyed by everything they depend on
#: (see ``evaluate_many``); cleared when it would grow past MEMO_MAX_BYTES.
_MEMO: dict[bytes, np.ndarray] = {}
_MEMO_LOCK = threading.Lock()
MEMO_MAX_BYTES = 64 * 2 ** 20


def evaluate_many(cfg: RavenSweepConfig, geometries, alphas_deg, betas_deg, isos, intervals=None):
    """Metrics (G*A*B*I, 6) of every design of G geometries, geometry-major (``evaluate_geometries``).

    Geometries whose ports and shoulder axes come out identical share one
    evaluation: in this batch, and across batches of this process (a memo
    keyed by the exact ports, axes, plane and design lists). In the paper's
    Table II with horizontal shoulder axes along x, phi_x turns each axis
    about itself, so its five values give one geometry: 400 of the 2000 are
    distinct. ``intervals``: ``psi_intervals`` for these alphas, betas,
    Iso_mins, when already known (they do not depend on the geometry).
    """
    from surgopt.kinematics.raven import evaluate_geometries

    geo = cfg.geometry
    per = len(alphas_deg) * len(betas_deg) * len(isos)
    pa = [arms(geo, *g) for g in geometries]
    ports = np.array([p for p, _ in pa], dtype=np.float64).reshape(len(pa), geo.n_arms, 3) + 0.0  # -0.0 -> 0.0
    axes = np.array([a for _, a in pa], dtype=np.float64).reshape(len(pa), geo.n_arms, 3) + 0.0
    al = np.radians(np.asarray(alphas_deg, float))
    be = np.radians(np.asarray(betas_deg, float))
    iso = np.asarray(isos, float)
    context = np.concatenate([[geo.depth_mm, geo.step_mm, geo.d4_max_mm, *geo.theta2_range_deg, len(al), len(be)],
                              al, be, iso]).tobytes()
    keys = [context + ports[g].tobytes() + axes[g].tobytes() for g in range(len(pa))]
    out = np.zeros((len(pa) * per, 6))
    todo: dict[bytes, list[int]] = {}
    with _MEMO_LOCK:
        for g, key in enumerate(keys):
            if key in _MEMO:
                out[g * per:(g + 1) * per] = _MEMO[key]
            else:
                todo.setdefault(key, []).append(g)
    if not todo:
        return out
    first = [gs[0] for gs in todo.values()]
    plo, phi_, has = intervals if intervals is not None else psi_intervals(cfg, al, be, iso)
    fresh = np.zeros((len(first) * per, 6))
    evaluate_geometries(np.ascontiguousarray(ports[first]), np.ascontiguousarray(axes[first]), float(geo.depth_mm),
                        float(geo.step_mm), float(geo.d4_max_mm), al, be, iso, plo, phi_, has, fresh)
    with _MEMO_LOCK:
        if (len(_MEMO) + len(todo)) * fresh.itemsize * per * 6 > MEMO_MAX_BYTES:
            _MEMO.clear()
        for u, (key, gs) in enumerate(todo.items()):
            block = fresh[u * per:(u + 1) * per]
            _MEMO[key] = block
            for g in gs:
                out[g * per:(g + 1) * per] = block
    return out


def _rows(params: np.ndarray, metrics: np.ndarray, step_mm: float, ids: np.ndarray, source: str) -> dict:
    area_cm2 = metrics[:, 0] / 100.0
    per_cm = metrics[:, 1] / 10.0
    zeta = np.where(per_cm > 0, area_cm2 / np.where(per_cm > 0, per_cm, 1.0), 0.0)
    n_pts = metrics[:, 2]
    iso_sum = metrics[:, 3]
    a3 = np.radians(params[:, 0]) ** 3 + np.radians(params[:, 1]) ** 3
    cols = {"design_id": ids.astype(np.int64)}
    for i, p in enumerate(PARAMS):
        cols[p] = params[:, i].copy()
    cols.update({
        "area_cm2": area_cm2, "perimeter_cm": per_cm, "zeta_cm": zeta, "iso_sum": iso_sum,
        "iso_mean": np.where(n_pts > 0, iso_sum / np.where(n_pts > 0, n_pts, 1.0), 0.0),
        "iso_area_cm2": iso_sum * step_mm * step_mm / 100.0,
        "iso_min_actual": metrics[:, 4], "n_points": n_pts.astype(np.int64),
        "cost": zeta * iso_sum * params[:, 7] / a3,
        "source": [source] * len(ids),
    })
    return cols


def schema():
    import pyarrow as pa

    return pa.schema(
        [pa.field("design_id", pa.int64())] + [pa.field(p, pa.float64()) for p in PARAMS] +
        [pa.field(c, pa.float64()) for c in ("area_cm2", "perimeter_cm", "zeta_cm", "iso_sum", "iso_mean",
                                             "iso_area_cm2", "iso_min_actual")] +
        [pa.field("n_points", pa.int64()), pa.field("cost", pa.float64(), metadata={"eq": "43"}),
         pa.field("source", pa.string())])


def auto_chunk(cfg: RavenSweepConfig) -> int:
    """Geometries per task: about two seconds of single-core work, and at least 32 tasks."""
    from surgopt.studies import chunk_for_seconds

    sw, geo = cfg.sweep, cfg.geometry
    if cfg.search == "refine":
        return 1
    reach = math.sqrt(geo.d4_max_mm ** 2 - geo.depth_mm ** 2)
    nodes = (2 * reach / geo.step_mm) ** 2
    designs = len(values(sw.alpha_deg)) * len(values(sw.beta_deg)) * len(values(sw.iso_min))
    return chunk_for_seconds(len(geometry_grid(cfg)), nodes * designs * NS_PER_NODE_DESIGN * 1e-9)


def n_tasks(cfg: RavenSweepConfig, chunk: int) -> int:
    if cfg.search == "refine":
        return len(cfg.refine.starts or [])
    return max(1, math.ceil(len(geometry_grid(cfg)) / chunk))


def warm_up(cfg: RavenSweepConfig) -> None:
    small = cfg.model_copy(update={"geometry": cfg.geometry.model_copy(update={"step_mm": 20.0})})
    evaluate(small, (0.0, 0.0, 0.0, 100.0, 50.0), [45.0], [45.0], [0.5])


def compute_task(cfg: RavenSweepConfig, chunk: int, index: int) -> dict:
    if cfg.search == "refine":
        return refine_from(cfg, cfg.refine.starts[index], index)
    sw = cfg.sweep
    al, be, iso = values(sw.alpha_deg), values(sw.beta_deg), values(sw.iso_min)
    per_geo = len(al) * len(be) * len(iso)
    geos = geometry_grid(cfg)
    g0, g1 = index * chunk, min(len(geos), (index + 1) * chunk)
    params = []
    design = np.array(list(itertools.product(al, be, iso)))  # (per_geo, 3)
    for g in geos[g0:g1]:
        p = np.empty((per_geo, 8))
        p[:, 0], p[:, 1], p[:, 7] = design[:, 0], design[:, 1], design[:, 2]
        p[:, 2:7] = g
        params.append(p)
    metrics = evaluate_many(cfg, geos[g0:g1], al, be, iso)
    ids = np.arange(g0 * per_geo, g1 * per_geo)
    return _rows(np.vstack(params), metrics, cfg.geometry.step_mm, ids, "grid")


def _bounds(cfg: RavenSweepConfig):
    return [(min(values(getattr(cfg.sweep, p))), max(values(getattr(cfg.sweep, p)))) for p in PARAMS]


def _cost_of(cfg: RavenSweepConfig, x) -> tuple[float, np.ndarray]:
    m = evaluate(cfg, tuple(x[2:7]), [x[0]], [x[1]], [x[7]])
    row = _rows(np.asarray([x]), m, cfg.geometry.step_mm, np.zeros(1), "refine")
    return float(row["cost"][0]), m[0]


def refine_from(cfg: RavenSweepConfig, start, index: int) -> dict:
    """Compass (coordinate) search inside the sweep's bounds from one grid design.

    Each parameter is tried at +-step; an improvement moves there; when no
    direction improves every step halves. Steps start at half the grid
    spacing (or 1/8 of the range for listed values). Stops after
    ``refine.max_evals`` evaluations or when steps fall below 1e-3 of the range.
    """
    bounds = _bounds(cfg)
    x = np.array(start, float)
    steps = []
    for p, (lo, hi) in zip(PARAMS, bounds):
        spec = getattr(cfg.sweep, p)
        steps.append(spec.step / 2 if isinstance(spec, Span) else (hi - lo) / 8 or 0.0)
    steps = np.array(steps)
    best, best_m = _cost_of(cfg, x)
    params, metrics = [x.copy()], [best_m]
    evals = 1
    while evals < cfg.refine.max_evals and np.any(steps > 1e-3 * np.maximum(1e-9, [hi - lo for lo, hi in bounds])):
        improved = False
        for i in range(8):
            if steps[i] == 0:
                continue
            for sgn in (1.0, -1.0):
                y = x.copy()
                y[i] = min(bounds[i][1], max(bounds[i][0], y[i] + sgn * steps[i]))
                if y[i] == x[i]:
                    continue
                c, m = _cost_of(cfg, y)
                evals += 1
                params.append(y.copy())
                metrics.append(m)
                if c > best:
                    best, x, improved = c, y, True
                    break
            if evals >= cfg.refine.max_evals:
                break
        if not improved:
            steps = steps / 2
    ids = np.arange(len(params)) + index * 1_000_000
    return _rows(np.vstack(params), np.vstack(metrics), cfg.geometry.step_mm, ids, "refine")


def refine_config(cfg: RavenSweepConfig, table) -> RavenSweepConfig:
    """The refine study for a grid table: starts at its top-k designs by cost."""
    import pyarrow.compute as pc

    top = table.take(pc.sort_indices(table["cost"], sort_keys=[("cost", "descending")])[:cfg.refine.top_k])
    starts = [[top[p][i].as_py() for p in PARAMS] for i in range(top.num_rows)]
    return cfg.model_copy(update={"search": "refine", "refine": cfg.refine.model_copy(update={"starts": starts})})


def paper_optimum_rank(table):
    """(rank by cost, row) of the Table II optimum in a grid table, or None if not in the grid."""
    import pyarrow.compute as pc

    mask = None
    for p, v in PAPER_OPTIMUM.items():
        m = pc.less(pc.abs(pc.subtract(table[p], v)), 1e-9)
        mask = m if mask is None else pc.and_(mask, m)
    hit = table.filter(mask)
    if hit.num_rows == 0:
        return None
    c = hit["cost"][0].as_py()
    rank = int(pc.sum(pc.greater(table["cost"], c)).as_py()) + 1
    return rank, {k: hit[k][0].as_py() for k in hit.column_names}


def feasibility(table) -> dict:
    import pyarrow.compute as pc

    f = int(pc.sum(pc.greater(table["n_points"], 0)).as_py() or 0)
    return {"with_common_workspace": f, "without": table.num_rows - f}


def summarize(table) -> dict:
    import pyarrow.compute as pc

    out = {"designs": table.num_rows, "with_common_workspace": int(pc.sum(pc.greater(table["n_points"], 0)).as_py() or 0)}
    if table.num_rows:
        i = int(pc.index(table["cost"], pc.max(table["cost"])).as_py())
        out.update({f"best_{p}": table[p][i].as_py() for p in PARAMS})
        out.update({"best_cost": table["cost"][i].as_py(), "best_zeta_cm": table["zeta_cm"][i].as_py()})
    r = paper_optimum_rank(table)
    if r is not None:
        out.update({"paper_optimum_rank": r[0], "paper_optimum_cost": r[1]["cost"]})
    return out


def tables(table):
    import pyarrow.compute as pc

    top = table.take(pc.sort_indices(table["cost"], sort_keys=[("cost", "descending")])[:10])
    cols = list(PARAMS) + ["zeta_cm", "area_cm2", "iso_mean", "cost"]
    rows = [[f"{top[c][i].as_py():.4g}" for c in cols] for i in range(top.num_rows)]
    return [("top designs by cost C (eq. 43)", cols, rows)]


def design_fields(cfg: RavenSweepConfig, params: dict):
    """Plane grid and margins of one design, per arm and common (for figures).

    Returns xs, ys (mm), per-arm margin (arms, nx, ny) and the common margin
    (nx, ny); a margin is positive inside, zero on the boundary (mm).
    """
    from surgopt.kinematics.raven import arm_cone_geometry

    geo = cfg.geometry
    g = tuple(params[p] for p in ("phi_x_deg", "phi_y_deg", "phi_z_deg", "bx_mm", "by_mm"))
    ports, axes = arms(geo, *g)
    reach = math.sqrt(geo.d4_max_mm ** 2 - geo.depth_mm ** 2)
    s = geo.step_mm
    lo = ports[:, :2].min(axis=0) - reach
    hi = ports[:, :2].max(axis=0) + reach
    xs = np.arange(math.floor(lo[0] / s) - 2, math.ceil(hi[0] / s) + 3) * s
    ys = np.arange(math.floor(lo[1] / s) - 2, math.ceil(hi[1] / s) + 3) * s
    n = xs.size * ys.size
    al, be = math.radians(params["alpha_deg"]), math.radians(params["beta_deg"])
    plo, phi_, has = psi_intervals(cfg, np.array([al]), np.array([be]), np.array([params["iso_min"]]))
    margins = np.empty((len(ports), xs.size, ys.size))
    for a in range(len(ports)):
        c, dist = np.empty(n), np.empty(n)
        arm_cone_geometry(xs, ys, geo.depth_mm, ports[a], axes[a], c, dist)
        c_lo, c_hi = math.cos(phi_[0, 0, 0]), math.cos(plo[0, 0, 0])
        m = np.minimum(geo.d4_max_mm - dist, np.minimum((c - c_lo) * dist, (c_hi - c) * dist))
        margins[a] = (m if has[0, 0, 0] else np.full(n, -1.0)).reshape(xs.size, ys.size)
    return xs, ys, ports, margins, margins.min(axis=0)


def feasible_mask(table):
    return table["n_points"].to_numpy() > 0
