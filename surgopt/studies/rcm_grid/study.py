"""Study ``rcm-grid``: GII of candidate RCM locations for any serial arm (Locke & Patel 2007).

config -> candidate list -> chunks -> kernel -> rows. Paper Sections II-III:
alternative Jacobian (eq. 8) under the RCM constraint, reverse Jacobian
(eqs. 5-6), joint-speed scaling, GII (eq. 7) over a 17^3 cube 100 mm below
the RCM, for a 121 x 121 x-z grid of candidates (Fig. 3) or a list (Table I).
The PA10-7C runs on its closed-form kernel (``kinematics/pa10_rcm``); every other arm (a shipped
model, a URDF file, a DH table; and the PA10 with ``robot.kernel = "generic"``) on the serial-chain
kernel (``kinematics/serial_chain``). Both reduce through one metric (``kinematics/rcm_metric``).
The config models are in ``rcm_grid_config``. One module of ~430 lines: the study's declaration
(config -> candidates -> the two kernels behind one interface -> rows, the cull search, the summary)
read as one.
"""
from __future__ import annotations

import math

import numpy as np

from surgopt.metrics import METRIC_RCM, POSE_METRICS, global_isotropy_index
from surgopt.studies.rcm_grid import HELP  # the command's help, read by the CLI without importing this module
from surgopt.studies import Estimate, Flag, Study, Summary, figures_in, html_views_in, peak_bytes
from surgopt.studies.rcm_grid.config import (  # noqa: F401 - the config models, re-exported
    SEARCH_OBJECTIVES,
    Candidates,
    Grid,
    RcmGridConfig,
    Robot,
    Workspace,
)
from surgopt.plans.search import SearchPlan, objectives_of, optimiser_of

NAME = "rcm-grid"
CONFIG_HELP = ("TOML or YAML config. Without it: the paper's setup (121 x 121 RCM candidates, "
               "17^3-point 50 mm cube, PA10-7C, 587 mm tool), or with --robot that arm's own default study.")
#: Bump when a kernel change alters results: stored runs then miss the cache.
KERNEL_VERSION = "rcm-5"  # rcm-5: the generic kernel walks in SIMD lanes (rows move by rounding, <= 2.1e-10 in GII)
DEFAULT_CONFIG = "rcm_locke_patel_2007.toml"
#: Cost model for choosing chunks: ~15 ns per pose of the cube on one core (the kernel
#: evaluates the mirror half, ~30 ns per evaluated pose; docs/performance.md).
NS_PER_POSE = 15.0
#: Column to rank designs by (descending) and key columns for baseline checks.
OBJECTIVE = "gii"
KEY_COLUMNS = ("candidate_id",)
#: Locke & Patel's Table I: (x, z) m with z from the shoulder, and the printed GII.
PAPER_TABLE_I = (
    (0.550, -0.540, 0.0357), (0.630, -0.570, 0.0351), (0.715, -0.630, 0.0148),
    (0.530, -0.410, 0.0421), (0.630, -0.390, 0.0340), (0.720, -0.370, 0.0107),
    (0.460, -0.300, 0.0356), (0.535, -0.210, 0.0440), (0.650, -0.160, 0.0139),
    (0.350, -0.210, 0.0228), (0.400, -0.110, 0.0293), (0.430, 0.010, 0.0332),
    (0.260, -0.140, 0.0110), (0.260, -0.060, 0.0111), (0.260, 0.030, 0.0111))


Config = RcmGridConfig


# ---------------------------------------------------------------------------
# config -> arrays
# ---------------------------------------------------------------------------


optimiser = optimiser_of  # the [search] optimiser of a config, or None (the full map or the cull)


def search_axes(cfg: RcmGridConfig) -> tuple[str, ...]:
    """The grid's varying coordinates an optimiser searches: x and z, and y when the grid has a y range."""
    g = cfg.candidates.grid
    return ("x", "y", "z") if g is not None and g.y_count > 1 else ("x", "z")


def search_plan(cfg: RcmGridConfig) -> SearchPlan | None:
    """An optimiser's space: the grid's x and z (and y) ranges as continuous bounds (m)."""
    spec = optimiser(cfg)
    if spec is None:
        return None
    g = cfg.candidates.grid
    bounds = {f"{a}_rcm_m": (getattr(g, f"{a}_min_m"), getattr(g, f"{a}_max_m")) for a in search_axes(cfg)}
    return SearchPlan(spec, bounds, objectives_of(spec, OBJECTIVE))


def candidate_xyz(cfg: RcmGridConfig) -> np.ndarray:
    """(M, 3) candidate (x, y, z) in config coordinates; a grid in x-major, then y, then z order (with
    one y this is the paper's x-major x-z order)."""
    c = cfg.candidates
    if c.list_m is not None:
        return with_y(cfg, np.asarray(c.list_m, dtype=np.float64))
    g = c.grid
    axes = [np.linspace(getattr(g, f"{a}_min_m"), getattr(g, f"{a}_max_m"), getattr(g, f"{a}_count"))
            for a in "xyz"]
    return np.stack([v.ravel() for v in np.meshgrid(*axes, indexing="ij")], axis=1)


def design_xyz(cfg: RcmGridConfig, x: np.ndarray) -> np.ndarray:
    """(M, 3) candidates from designs in ``search_axes`` order (x, z: at the grid's y)."""
    return with_y(cfg, np.asarray(x, dtype=np.float64).reshape(-1, len(search_axes(cfg))))


def with_y(cfg: RcmGridConfig, pts: np.ndarray) -> np.ndarray:
    """(M, 3) from (M, 2) x-z points at the grid's y (0 without a grid), or (M, 3) as they are."""
    if pts.shape[1] == 3:
        return pts
    y = 0.0 if cfg.candidates.grid is None else cfg.candidates.grid.y_min_m
    return np.stack([pts[:, 0], np.full(pts.shape[0], y), pts[:, 1]], axis=1)


def design_box(cfg: RcmGridConfig) -> list:
    """The candidate grid's box: x, y and z where the grid varies them (a candidate list has no box)."""
    from surgopt.studies import Edge

    g = cfg.candidates.grid
    if g is None:
        return []
    return [Edge(f"{a}_rcm_m", getattr(g, f"{a}_min_m"), getattr(g, f"{a}_max_m"), f"candidates.grid.{a}_min_m",
                 f"candidates.grid.{a}_max_m") for a in "xyz" if getattr(g, f"{a}_count") > 1]


def candidate_count(cfg: RcmGridConfig) -> int:
    """Candidates a config's own plan evaluates (an optimiser's: its trials)."""
    spec = optimiser(cfg)
    c = cfg.candidates
    if spec is not None:
        return spec.trials
    if c.list_m is not None:
        return len(c.list_m)
    return c.grid.x_count * c.grid.y_count * c.grid.z_count


def candidate_rcms(cfg: RcmGridConfig, xyz: np.ndarray) -> np.ndarray:
    """(M, 3) RCM positions in the base frame (z shifted by d1 when shoulder-relative)."""
    dz = cfg.robot.link_d1_m if cfg.candidates.z_reference == "shoulder" else 0.0
    out = np.array(xyz, dtype=np.float64, copy=True)
    out[:, 2] += dz
    return out


def workspace_offsets(ws: Workspace) -> np.ndarray:
    """(P, 3) tip positions relative to the RCM: the cube grid of Sec. III-B (x-major order)."""
    n = ws.points_per_side
    t = np.linspace(-ws.cube_side_m / 2, ws.cube_side_m / 2, n) if n > 1 else np.zeros(1)
    t = 0.5 * (t - t[::-1])  # exactly symmetric about 0, so the kernel can use the mirror symmetry in y
    X, Y, Z = np.meshgrid(t, t, t - ws.depth_below_rcm_m, indexing="ij")
    return np.ascontiguousarray(np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1))


def arm_model(cfg: RcmGridConfig):
    """The closed-form kernel's ``Pa10Arm`` for this config."""
    from surgopt.kinematics.pa10_rcm import Pa10Arm
    from surgopt.robots import pa10_7c

    r = cfg.robot
    lim = r.joint_limit_deg
    spd = r.max_joint_speed_rad_s
    names = pa10_7c.ACTIVE_JOINTS
    cos_limit = np.array([math.cos(min(math.radians(getattr(lim, j)), math.pi)) for j in names])
    qdot = np.array([getattr(spd, j) for j in names], dtype=np.float64)
    links = np.array([r.link_d1_m, r.link_d3_m, r.link_d5_m])
    return Pa10Arm(links, r.tool_offset_pa10_m, 1.0 if r.elbow == "up" else -1.0, qdot, cos_limit)


# ---------------------------------------------------------------------------
# the two kernels behind one interface
# ---------------------------------------------------------------------------


class ClosedFormKernel:
    """The PA10-7C's closed-form IK kernel (``kinematics/pa10_rcm``): the paper setup's default path."""

    def __init__(self, cfg: RcmGridConfig):
        self.arm = arm_model(cfg)

    def extremes(self, rcms, offsets, side):
        """(sigma_min, sigma_max, n_unreachable, n_singular, points_evaluated) per candidate over
        ``offsets`` (a ``side``^3 cube or subset, x-major)."""
        from surgopt.kinematics.pa10_rcm import rcm_candidates_extremes

        lo, hi, n_unr, n_sing = rcm_candidates_extremes(rcms, offsets, self.arm)
        return lo, hi, n_unr, n_sing, np.full(rcms.shape[0], offsets.shape[0])

    def bounded(self, rcm, offsets, side, gii_to_beat):
        """One candidate until its running GII bound falls to ``gii_to_beat`` (Culling): corner-most
        points first, in blocks of CULL_BLOCK."""
        from surgopt.kinematics.pa10_rcm import rcm_candidate_bounded

        radius = np.abs(offsets - offsets.mean(axis=0)).sum(axis=1)
        order = np.argsort(-radius, kind="stable")
        return rcm_candidate_bounded(rcm, np.ascontiguousarray(offsets[order]), self.arm, gii_to_beat, CULL_BLOCK)

    def warm_up(self, offsets, side):
        from surgopt.kinematics import pa10_rcm as k

        rcm, off = np.array([[0.5, 0.0, 0.1]]), np.array([[0.0, 0.0, -0.1]])
        k.rcm_candidates_extremes(rcm, off, self.arm)
        k.rcm_candidate_bounded(rcm[0], off, self.arm, 0.0, 64)


class ChainKernel:
    """The generic serial-chain kernel (``kinematics/serial_chain``): any arm, RCM-constrained Newton IK
    walked through the cube in serpentine order from the seed."""

    def __init__(self, cfg: RcmGridConfig):
        self.chain, self.names, self.seed = cfg.robot.chain()
        self.metric = pose_metric(cfg)
        self.params = cfg.metric_params() if hasattr(cfg, "metric_params") else ()

    def _walk(self, offsets, side):
        from surgopt.kinematics.serial_chain import serpentine_order

        return np.ascontiguousarray(offsets[serpentine_order(side)]) if side ** 3 == offsets.shape[0] else offsets

    def extremes(self, rcms, offsets, side):
        from surgopt.kinematics.chain_candidates import chain_candidates_extremes

        return chain_candidates_extremes(rcms, self._walk(offsets, side), self.chain, self.seed,
                                         metric=self.metric, metric_params=self.params)

    def bounded(self, rcm, offsets, side, gii_to_beat):
        from surgopt.kinematics.chain_candidates import chain_candidates_extremes

        r = chain_candidates_extremes(rcm[None], self._walk(offsets, side), self.chain, self.seed,
                                      gii_to_beat=[gii_to_beat], metric=self.metric, metric_params=self.params)
        return tuple(v[0] for v in r)

    def warm_up(self, offsets, side):
        """One candidate over the config's own cube: the walk its chunks take (in SIMD lanes from
        ``serial_lanes.MIN_POINTS_PER_LANE`` points a lane, scalar below), so no chunk compiles."""
        self.extremes(np.array([[0.5, 0.0, 0.1]]), offsets, side)


def kernel_for(cfg: RcmGridConfig):
    """The closed-form PA10 kernel for the paper setup (``robot.kernel`` auto/closed_form), else the chain
    kernel (and for ``metric = "standard"``, which only the chain kernel computes)."""
    return kernel_type(cfg)(cfg)


# ---------------------------------------------------------------------------
# study protocol
# ---------------------------------------------------------------------------


def pose_metric(config=None):
    """The per-pose metric (``metrics.POSE_METRICS``) of a config: a validated one, or one as stored (a dict)."""
    name = config.get("metric") if isinstance(config, dict) else getattr(config, "metric", None)
    return POSE_METRICS[name or "alternative"]


def schema(config=None):
    """The rows' schema; the singular values' columns are named for the config's metric with their unit
    (``sigma_min_m_per_s`` for the RCM metric, ``sigma_min_task_scaled`` for the dimensionless standard one)."""
    import pyarrow as pa

    metric = pose_metric(config)
    lo, hi = metric.sigma_columns
    return pa.schema(
        [
            pa.field("candidate_id", pa.int64()),
            pa.field("x_rcm_m", pa.float64()),
            pa.field("y_rcm_m", pa.float64()),
            pa.field("z_rcm_m", pa.float64(), metadata={"reference": "see config candidates.z_reference"}),
            pa.field("gii", pa.float64(), metadata={"eq": "7", "unit": "1"}),
            pa.field("feasible", pa.bool_()),
            pa.field(lo, pa.float64(), metadata={"unit": metric.unit, "meaning": "min over the workspace of the "
                                                 f"smallest {metric.meaning}"}),
            pa.field(hi, pa.float64(), metadata={"unit": metric.unit, "meaning": "max over the workspace of the "
                                                 f"largest {metric.meaning}"}),
            pa.field("n_unreachable", pa.int64(),
                     metadata={"meaning": "closed-form kernel: unreachable points; generic kernel: 1 when the walk "
                                          "stopped at an unreachable point (the rest is not tried)"}),
            pa.field("n_singular", pa.int64()),
            pa.field("points_evaluated", pa.int64()),
            pa.field("gii_is_exact", pa.bool_(),
                     metadata={"meaning": "false for candidates culled by --cull: gii is then an upper bound"}),
        ]
    )


#: Cost model of the generic kernel: ~800 ns per pose of a feasible candidate on one core
#: (docs/performance.md, benchmarks/bench_rcm.py); infeasible candidates stop at their first unreachable point.
NS_PER_POSE_CHAIN = 800.0


def ns_per_pose(cfg: RcmGridConfig) -> float:
    return NS_PER_POSE if kernel_type(cfg) is ClosedFormKernel else NS_PER_POSE_CHAIN * pose_metric(cfg).relative_cost


def kernel_type(cfg) -> type:
    """Which kernel ``kernel_for`` would build, without building it."""
    rcm_metric = pose_metric(cfg).code == METRIC_RCM  # the closed form computes the RCM metric only
    return ClosedFormKernel if cfg.robot.closed_form and rcm_metric else ChainKernel


def auto_chunk(cfg: RcmGridConfig) -> int:
    """Candidates per task: about TARGET_TASK_S (1 s) of single-core work, and at least 32 tasks."""
    from surgopt.studies import chunk_for_seconds

    return chunk_for_seconds(candidate_count(cfg), cfg.workspace.points_per_side ** 3 * ns_per_pose(cfg) * 1e-9)


#: Time model of the estimate: ~8.5 ns per pose of the cube on one core, measured over the paper map
#: (infeasible candidates cost less, the mirror half is already in it); docs/performance.md. The generic
#: kernel: NS_PER_POSE_CHAIN_EST, measured over the shipped models' default maps (about half infeasible): with
#: the run's fixed overhead (runner.RUN_OVERHEAD_S) estimated at 2.8 / 2.3 / 1.9 s against 3.0 / 2.6 / 2.1 s measured
#: for the UR5e / Panda / LBR iiwa (benchmarks/bench_readme_estimates.py).
NS_PER_POSE_EST = 8.5
NS_PER_POSE_CHAIN_EST = 250.0


def estimate(cfg: RcmGridConfig) -> Estimate:
    """Candidates x cube points at NS_PER_POSE_EST (--cull: about a tenth of that); a row is ~83 bytes."""
    m = candidate_count(cfg)
    p = cfg.workspace.points_per_side ** 3
    ns = (NS_PER_POSE_EST if kernel_type(cfg) is ClosedFormKernel
          else NS_PER_POSE_CHAIN_EST * pose_metric(cfg).relative_cost)
    seconds = m * p * ns * 1e-9 * (0.1 if cfg.search == "cull" else 1.0)
    return Estimate(items=m, what="RCM candidates", rows=m, seconds_one_core=seconds,
                    peak_bytes=peak_bytes(m, 83, working_bytes=m * 72 + p * 200))


def n_tasks(cfg: RcmGridConfig, chunk: int) -> int:
    """Chunks of the candidate grid."""
    return max(1, math.ceil(candidate_count(cfg) / chunk))


def warm_up(cfg: RcmGridConfig) -> None:
    """Compile (or load from the on-disk cache) the kernels the config's chunks call, in the parent."""
    kernel_for(cfg).warm_up(workspace_offsets(cfg.workspace), cfg.workspace.points_per_side)


def _rows(cfg, ids, xyz, lo, hi, n_unr, n_sing, n_eval, exact):
    feasible = n_unr == 0
    gii = global_isotropy_index(lo, hi, feasible)
    lo_name, hi_name = pose_metric(cfg).sigma_columns
    return {
        "candidate_id": ids.astype(np.int64),
        "x_rcm_m": xyz[:, 0].copy(),
        "y_rcm_m": xyz[:, 1].copy(),
        "z_rcm_m": xyz[:, 2].copy(),
        "gii": gii,
        "feasible": feasible,
        lo_name: np.where(np.isfinite(lo), lo, 0.0),
        hi_name: hi,
        "n_unreachable": np.asarray(n_unr).astype(np.int64),
        "n_singular": np.asarray(n_sing).astype(np.int64),
        "points_evaluated": np.asarray(n_eval).astype(np.int64),
        "gii_is_exact": exact,
    }


def compute_task(cfg: RcmGridConfig, chunk: int, index: int) -> dict:
    """Rows for candidates [index*chunk, (index+1)*chunk) of the full map (the cull is its own plan)."""
    xyz_all = candidate_xyz(cfg)
    ids = np.arange(index * chunk, min(xyz_all.shape[0], (index + 1) * chunk))
    return candidate_rows(cfg, ids, xyz_all[ids])


def evaluate_designs(cfg: RcmGridConfig, x: np.ndarray, ids: np.ndarray, source: str) -> dict:
    """Rows of any candidates (rows of ``x`` in ``search_axes`` order; a plan's batch: ids are its trial numbers)."""
    return candidate_rows(cfg, np.asarray(ids), design_xyz(cfg, x))


def candidate_rows(cfg: RcmGridConfig, ids: np.ndarray, xyz: np.ndarray) -> dict:
    """The full-map rows of these candidates (every cube point evaluated)."""
    offsets = workspace_offsets(cfg.workspace)
    lo, hi, n_unr, n_sing, n_eval = kernel_for(cfg).extremes(candidate_rcms(cfg, xyz), offsets,
                                                             cfg.workspace.points_per_side)
    return _rows(cfg, ids, xyz, lo, hi, n_unr, n_sing, n_eval, np.ones(ids.shape[0], bool))


#: Points per culling block of the closed-form kernel: small enough to stop early, large enough to vectorise.
CULL_BLOCK = 128


def cull_search(cfg: RcmGridConfig) -> dict:
    """Exact argmax of the GII with the Culling algorithm of Stocco & Salcudean.

    1. Every candidate is evaluated on the 27 points {first, middle, last}^3 of
       the workspace grid: a GII over a subset bounds the full GII from above.
    2. Candidates are visited by decreasing bound. Each is evaluated on the
       full workspace (the closed-form kernel: corner-most points first; the chain kernel: along its
       walk) and dropped as soon as its running bound falls to the best GII found so far. Once a
       candidate's subset bound is at or below the best, all later ones are culled too.
    Rows: every candidate, ``gii_is_exact`` false where culled (gii is then
    the upper bound reached when it was dropped).
    """
    xyz = candidate_xyz(cfg)
    rcms = candidate_rcms(cfg, xyz)
    kernel = kernel_for(cfg)
    n = cfg.workspace.points_per_side
    offsets = workspace_offsets(cfg.workspace)
    pick = sorted({0, n // 2, n - 1})
    sub = np.array([(i * n + j) * n + k for i in pick for j in pick for k in pick])
    lo, hi, n_unr, n_sing, n_eval = (np.array(v) for v in kernel.extremes(rcms, offsets[sub], len(pick)))
    ub = global_isotropy_index(lo, hi, n_unr == 0)
    exact = np.zeros(xyz.shape[0], bool)
    best = 0.0
    for i in np.argsort(-ub, kind="stable"):
        if n_unr[i] > 0:
            exact[i] = True  # infeasible, known exactly
            continue
        if ub[i] <= best:
            continue
        lo[i], hi[i], n_unr[i], n_sing[i], n_eval[i] = kernel.bounded(rcms[i], offsets, n, best)
        if n_eval[i] == offsets.shape[0] and n_unr[i] == 0:
            exact[i] = True
            best = max(best, float(global_isotropy_index(lo[i], hi[i])))
        elif n_unr[i] > 0:
            exact[i] = True
    return _rows(cfg, np.arange(xyz.shape[0]), xyz, lo, hi, n_unr, n_sing, n_eval, exact)


def summary(parts) -> Summary:
    """Feasible count, the best feasible candidate whose GII is exact, and the five best such candidates
    (``parts``: a ``surgopt.parts.Parts``, read part by part)."""
    n = parts.num_rows
    feasible = parts.count(lambda t: t["feasible"], columns=["feasible"])
    counts = {"feasible": feasible, "infeasible": n - feasible}
    headline = {"candidates": n, "feasible": feasible}
    import pyarrow.compute as pc

    top = parts.top("gii", 5, where=lambda t: pc.and_(t["gii_is_exact"], t["feasible"]))
    cols = ["x_rcm_m", "y_rcm_m", "z_rcm_m", "gii"]
    if top.num_rows:  # the best is a feasible candidate: one whose whole workspace is reachable
        headline.update({f"best_{k}": top[k][0].as_py() for k in cols})
    else:
        headline["best"] = "none: no candidate reaches the whole workspace" + why_none_feasible(parts, n)
    rows = [[f"{x:.3f}", f"{y:.3f}", f"{z:.3f}", f"{g:.5f}"] for x, y, z, g in zip(*(top[k].to_pylist() for k in cols))]
    return Summary(headline, counts, [("best RCM candidates", cols, rows)])


def why_none_feasible(parts, n: int) -> str:
    """Which constraint failed on how many candidates, when none is feasible (#28 item 3)."""
    import pyarrow.compute as pc

    if not n:
        return ""
    unreachable = parts.count(lambda t: pc.greater(t["n_unreachable"], 0), columns=["n_unreachable"])
    singular = parts.count(lambda t: pc.greater(t["n_singular"], 0), columns=["n_singular"])
    return (f" ({unreachable:,} of {n:,} candidates leave workspace points unreachable within the joint limits or "
            f"the tool's length, {singular:,} meet a singular pose)")


#: Branch search (``--branches``): random seeds within the joint limits, solutions closer than BRANCH_TOL_DEG in
#: every joint (angles wrapped) are one branch.
BRANCH_SAMPLES = 96
BRANCH_TOL_DEG = 60.0
#: Candidates tried, this many nearest the grid's centre, then as many spread over the grid, until one is reached.
BRANCH_PROBE_CANDIDATES = 25


def ik_branches(cfg: RcmGridConfig) -> list[dict[str, float]]:
    """The arm's IK branches at a reference candidate (#28): the configured seed's solution first (when it
    converges), then every distinct solution (joints in deg) of the RCM inverse kinematics at the workspace's
    centre reached from BRANCH_SAMPLES seeds drawn within the joint limits (a fixed random stream: the same
    branches every time). The reference is the first candidate some seed reaches, trying the
    BRANCH_PROBE_CANDIDATES nearest the grid's centre, then as many spread over the rest of the grid.
    Searched once per arm, workspace and grid in a process. Generic kernel arms only."""
    import json

    key = json.dumps(cfg.model_dump(mode="json", include={"robot", "workspace", "candidates"}), sort_keys=True)
    if key not in _BRANCHES:
        _BRANCHES[key] = _search_branches(cfg)
    return _BRANCHES[key]


_BRANCHES: dict = {}


def _probe_order(xyz: np.ndarray) -> np.ndarray:
    """Candidate indices for the branch search: the nearest the grid's centre, then a spread over the rest."""
    by_distance = np.argsort(np.linalg.norm(xyz - xyz.mean(axis=0), axis=1), kind="stable")
    near, rest = by_distance[:BRANCH_PROBE_CANDIDATES], by_distance[BRANCH_PROBE_CANDIDATES:]
    spread = rest[np.unique(np.linspace(0, len(rest) - 1, min(len(rest), BRANCH_PROBE_CANDIDATES)).astype(int))]
    return np.concatenate([near, spread]) if len(rest) else near


def _search_branches(cfg: RcmGridConfig) -> list[dict[str, float]]:
    from surgopt.kinematics.serial_chain import rcm_walk

    chain, names, seed = cfg.robot.chain()
    xyz = candidate_xyz(cfg)
    centre = workspace_offsets(cfg.workspace).mean(axis=0)[None, :]
    lo = np.where(np.isfinite(chain.lower), chain.lower, -np.pi)
    hi = np.where(np.isfinite(chain.upper), chain.upper, np.pi)
    rng = np.random.default_rng(2026)
    seeds = [np.asarray(seed, float)] + [lo + rng.uniform(size=5) * (hi - lo) for _ in range(BRANCH_SAMPLES)]
    for c in _probe_order(xyz):
        rcm = candidate_rcms(cfg, xyz[c:c + 1])[0]
        found = []
        for k, q0 in enumerate(seeds):  # the configured seed with the run's own restarts around it; samples alone
            q = rcm_walk(chain, rcm, centre, q0, restarts=None if k == 0 else np.zeros((0, 5)))["q"][0]
            if np.all(np.isfinite(q)) and not any(_same_branch(q, f, chain.prismatic) for f in found):
                found.append(q)
        if found:
            return [{n: round(float(v if p else np.degrees(v)), 3) for n, v, p in zip(names, q, chain.prismatic)}
                    for q in found]
    return []


def seed_advice(cfg: RcmGridConfig) -> list[str]:
    """For a URDF or DH arm given no seed_deg (#28 item 2) for which the branch search finds nothing (when it
    finds branches the command line runs each, seeded on it): one line on why no seed works."""
    r = cfg.robot
    if (r.urdf is None and r.dh is None) or r.seed_deg or ik_branches(cfg):
        return []
    return [f"robot: no seed within the joint limits ({BRANCH_SAMPLES} tried) reaches the workspace's centre from "
            f"any of {min(len(candidate_xyz(cfg)), 2 * BRANCH_PROBE_CANDIDATES)} candidates near the grid's centre "
            f"and spread over it: check robot.tool_length_m, workspace.depth_below_rcm_m, the locked joints and the "
            f"candidate grid"]


def branch_advice(cfg: RcmGridConfig) -> list[str]:
    """A shipped model run without ``--branches`` (#42 item 9): the map follows the one IK branch its seed
    lands on; say so, and how many the branch search finds at the grid's centre (``ik_branches``)."""
    from surgopt.robots.models import get_model

    r = cfg.robot
    if r.closed_form or r.urdf is not None or r.dh is not None or r.model is None:
        return []
    if r.seed_deg and dict(r.seed_deg) != dict(get_model(r.model).seed_deg or {}):
        return []  # a seed of the user's (or of a --branches run): the branch is chosen
    n = len(ik_branches(cfg))
    if n < 2:
        return []
    return [f"robot: the map follows one IK branch, the one {r.model}'s seed lands on; the branch search finds {n} "
            f"at the grid's centre, whose best RCM and GII can differ: --branches runs each"]


def unseeded_file_arm(cfg: RcmGridConfig) -> str | None:
    """Why ``--branches`` applies without the flag (#28 item 1): a URDF or DH arm given no seed_deg has no branch
    chosen for it, so the command line runs the map once per branch found and reports each and the best."""
    r = cfg.robot
    if (r.urdf is None and r.dh is None) or r.seed_deg:
        return None
    return ("robot: no seed_deg: the map runs once per IK branch found at the grid's centre, seeded on it "
            "(give robot.seed_deg to run one branch)")


def reach_grid_advice(cfg: RcmGridConfig) -> list[str]:
    """Says where a URDF or DH arm's candidate grid came from when the config left it out (#28 item 5)."""
    g = cfg.candidates.grid
    if g is None or not getattr(cfg, "grid_from_reach", False):
        return []
    step = (g.z_max_m - g.z_min_m) / max(1, g.z_count - 1) * 1000
    return [f"candidates: sized from the arm's reach: x {g.x_min_m:g} to {g.x_max_m:g} m, z {g.z_min_m:g} to "
            f"{g.z_max_m:g} m, {step:.0f} mm apart ({g.x_count * g.z_count:,} candidates, every RCM the tool can "
            f"hold; give candidates.grid to choose)"]


def _same_branch(a, b, prismatic) -> bool:
    d = np.where(prismatic > 0, np.abs(a - b) * 1000, np.degrees(np.abs((a - b + np.pi) % (2 * np.pi) - np.pi)))
    return bool(np.all(d < BRANCH_TOL_DEG))


def branch_variants(cfg: RcmGridConfig) -> list[tuple[str, RcmGridConfig]]:
    """``--branches``: the config once per IK branch (``ik_branches``), each seeded on it: (label, config)."""
    from surgopt.errors import UsageError

    if cfg.robot.closed_form:
        raise UsageError("--branches: the PA10's closed form takes its branch from robot.elbow (up or down); "
                         "branches are searched for the generic kernel's arms (URDF, DH, shipped models)")
    branches = ik_branches(cfg)
    if not branches:
        raise UsageError("--branches: no seed within the joint limits reaches the workspace's centre from any of "
                         "the candidates tried near the grid's centre and spread over it")
    robot = cfg.robot
    return [(f"branch={k}", cfg.model_copy(update={"robot": robot.model_copy(update={"seed_deg": b})}))
            for k, b in enumerate(branches)]


def robot_flag(value: str) -> dict:
    """``--robot NAME|FILE``: a shipped model by name, or a URDF file (relative to the working directory)."""
    from pathlib import Path

    from surgopt.errors import ConfigError
    from surgopt.robots.models import MODELS

    if value in MODELS:
        return {"robot.model": value, "robot.urdf": None}
    path = Path(value)
    if path.suffix.lower() == ".urdf" or path.exists():
        return {"robot.urdf": str(path.resolve()), "robot.model": None}
    raise ConfigError("--robot", f"{value!r} is neither a shipped model ({', '.join(MODELS)}) nor a URDF file")


def feasible_mask(table):
    return table["feasible"].to_numpy(zero_copy_only=False)


STUDY = Study(
    html_views=html_views_in("surgopt.studies.rcm_grid.html"),
    name=NAME, kernel_version=KERNEL_VERSION, config_model=RcmGridConfig, default_config=DEFAULT_CONFIG,
    help=HELP, config_help=CONFIG_HELP, schema=schema, key_columns=KEY_COLUMNS, objective=OBJECTIVE,
    auto_chunk=auto_chunk, n_tasks=n_tasks, warm_up=warm_up, compute_task=compute_task, summary=summary,
    feasible_mask=feasible_mask, feasible_columns=("feasible",), figures=figures_in("surgopt.studies.rcm_grid.figures"), estimate=estimate, search_plan=search_plan,
    warm_variants=(("metric=standard",), ("robot.model=ur5e",)),
    evaluate=evaluate_designs, design_box=design_box, cull=lambda cfg: cull_search(cfg),
    advice=lambda cfg: (cfg.robot.auto_lock_advice() + cfg.robot.tool_axis_advice() + reach_grid_advice(cfg)
                        + seed_advice(cfg) + branch_advice(cfg)),
    flags=(Flag("--cull", "Fast exact argmax with the Culling algorithm (Stocco & Salcudean) instead of "
                          "the full GII map; culled candidates carry an upper bound.",
                config_update={"search": "cull"}),
           Flag("--branches", "Find the arm's IK branches (seeds within the joint limits, distinct solutions at "
                              "the workspace's centre) and run the map once per branch, seeded on it: a table of "
                              "the best RCM per branch (generic-kernel arms; implied for a URDF or DH arm "
                              "given no robot.seed_deg).", expand=branch_variants, implied=unseeded_file_arm),
           Flag("--robot", "The arm: a shipped model (pa10_7c, ur5e, panda, lbr_iiwa_14) or a URDF file; "
                           "without a CONFIG, that model's own default study (docs/robots.md).",
                metavar="NAME|FILE", value_update=robot_flag)))
