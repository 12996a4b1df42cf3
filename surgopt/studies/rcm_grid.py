"""Study ``rcm-grid``: GII of candidate RCM locations for a PA10-7C (Locke & Patel 2007).

config -> candidate list -> chunks -> kernel -> rows. Paper Sections II-III:
alternative Jacobian (eq. 8) under the RCM constraint, reverse Jacobian
(eqs. 5-6), joint-speed scaling, GII (eq. 7) over a 17^3 cube 100 mm below
the RCM, for a 121 x 121 x-z grid of candidates (Fig. 3) or a list (Table I).
"""
from __future__ import annotations

import math
from typing import Annotated, Literal

import numpy as np
from pydantic import Field, model_validator

from surgopt.config import StrictModel
from surgopt.metrics import global_isotropy_index
from surgopt.robots import pa10_7c
from surgopt.studies import Estimate, Flag, Study, Summary, figures_in, peak_bytes
from surgopt.studies.search import SearchPlan, SearchSpec, check_objectives, objectives_of, optimiser_of, search_field

NAME = "rcm-grid"
HELP = """Global Isotropy Index of candidate remote-centre-of-motion locations for a PA10-7C
    (Locke & Patel, ICRA 2007: eqs. 5-9, Fig. 3, Table I).

    For every RCM candidate (x, z) the tool tip visits each point of a cube below the RCM with the
    tool axis through the RCM; closed-form IK (S3 = W2 = 0) and the alternative Jacobian under the RCM
    constraint give the reverse Jacobian J_r, scaled by the rated joint speeds. GII = min sigma_min /
    max sigma_max over the cube (eq. 7); a candidate with any unreachable point is infeasible.
    Rows: candidate_id, x_rcm_m, z_rcm_m, gii, feasible, sigma_min_m_per_s, sigma_max_m_per_s,
    n_unreachable, n_singular, points_evaluated, gii_is_exact.
    """
CONFIG_HELP = ("TOML or YAML config. Without it: the paper's setup (121 x 121 RCM candidates, "
             "17^3-point 50 mm cube, PA10-7C, 587 mm tool).")
#: Bump when a kernel change alters results: stored runs then miss the cache.
KERNEL_VERSION = "pa10-rcm-2"
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


#: Row columns a [search] may optimise.
SEARCH_OBJECTIVES = ("gii", "sigma_min_m_per_s", "sigma_max_m_per_s", "x_rcm_m", "z_rcm_m")


class JointLimitsDeg(StrictModel):
    """Symmetric joint ranges +-value (deg) of the five active joints [MHI]."""

    S1: float = Field(pa10_7c.JOINT_LIMIT_DEG["S1"], gt=0, le=360)
    S2: float = Field(pa10_7c.JOINT_LIMIT_DEG["S2"], gt=0, le=360)
    E1: float = Field(pa10_7c.JOINT_LIMIT_DEG["E1"], gt=0, le=360)
    E2: float = Field(pa10_7c.JOINT_LIMIT_DEG["E2"], gt=0, le=360)
    W1: float = Field(pa10_7c.JOINT_LIMIT_DEG["W1"], gt=0, le=360)


class JointSpeedsRadS(StrictModel):
    """Rated maximum speeds (rad/s): the diagonal of the scaling matrix Q [MHI]."""

    S1: float = Field(pa10_7c.MAX_JOINT_SPEED_RAD_S["S1"], gt=0)
    S2: float = Field(pa10_7c.MAX_JOINT_SPEED_RAD_S["S2"], gt=0)
    E1: float = Field(pa10_7c.MAX_JOINT_SPEED_RAD_S["E1"], gt=0)
    E2: float = Field(pa10_7c.MAX_JOINT_SPEED_RAD_S["E2"], gt=0)
    W1: float = Field(pa10_7c.MAX_JOINT_SPEED_RAD_S["W1"], gt=0)


class Robot(StrictModel):
    link_d1_m: float = Field(pa10_7c.LINKS_BIELEFELD_M[0], gt=0, le=5, description="base to shoulder (S2 axis)")
    link_d3_m: float = Field(pa10_7c.LINKS_BIELEFELD_M[1], gt=0, le=5, description="shoulder to elbow")
    link_d5_m: float = Field(pa10_7c.LINKS_BIELEFELD_M[2], gt=0, le=5, description="elbow to wrist centre")
    link_d7_m: float = Field(pa10_7c.LINKS_BIELEFELD_M[3], ge=0, le=5, description="wrist centre to flange")
    tool_length_m: float = Field(pa10_7c.TOOL_LENGTH_M, gt=0, le=5, description="end-effector + tool")
    tool_length_from: Literal["flange", "wrist_centre"] = "flange"
    elbow: Literal["up", "down"] = "up"
    joint_limit_deg: JointLimitsDeg = JointLimitsDeg()
    max_joint_speed_rad_s: JointSpeedsRadS = JointSpeedsRadS()

    @property
    def tool_offset_m(self) -> float:
        """Wrist centre to tool tip along the tool axis."""
        return self.tool_length_m + (self.link_d7_m if self.tool_length_from == "flange" else 0.0)


class Workspace(StrictModel):
    """Cube of tool-tip positions centred ``depth_below_rcm_m`` below the RCM."""

    cube_side_m: float = Field(0.05, gt=0, le=1)
    depth_below_rcm_m: float = Field(0.1, gt=0, le=2)
    points_per_side: int = Field(17, ge=1, le=101)


class Grid(StrictModel):
    x_min_m: float = Field(0.20, ge=-3, le=3)
    x_max_m: float = Field(0.80, ge=-3, le=3)
    x_count: int = Field(121, ge=1, le=2001)
    z_min_m: float = Field(-0.60, ge=-3, le=3)
    z_max_m: float = Field(0.00, ge=-3, le=3)
    z_count: int = Field(121, ge=1, le=2001)

    @model_validator(mode="after")
    def _ordered(self):
        if self.x_max_m < self.x_min_m:
            raise ValueError("x_max_m must be >= x_min_m")
        if self.z_max_m < self.z_min_m:
            raise ValueError("z_max_m must be >= z_min_m")
        return self


class Candidates(StrictModel):
    """RCM candidates in the x-z plane (y = 0): a grid, or an explicit list."""

    z_reference: Literal["shoulder", "base"] = "shoulder"
    grid: Grid | None = None
    list_m: list[Annotated[list[float], Field(min_length=2, max_length=2)]] | None = Field(
        None, min_length=1, max_length=1_000_000, description="[[x, z], ...] in metres")

    @model_validator(mode="after")
    def _one_kind(self):
        if self.grid is not None and self.list_m is not None:
            raise ValueError("give either grid or list_m, not both")
        if self.grid is None and self.list_m is None:
            object.__setattr__(self, "grid", Grid())
        return self


class RcmGridConfig(StrictModel):
    robot: Robot = Robot()
    workspace: Workspace = Workspace()
    candidates: Candidates = Candidates()
    search: search_field("full", "cull") = Field(
        "full", description="'full' map, 'cull' (exact argmax), or a [search] table (an optimiser over x, z)")

    @model_validator(mode="after")
    def _search_needs_a_grid(self):
        if isinstance(self.search, SearchSpec) and self.candidates.list_m is not None:
            raise ValueError("a [search] optimises over candidates.grid's x and z ranges: give a grid, not list_m")
        check_objectives(self.search, SEARCH_OBJECTIVES)
        return self


Config = RcmGridConfig


# ---------------------------------------------------------------------------
# config -> arrays
# ---------------------------------------------------------------------------


optimiser = optimiser_of  # the [search] optimiser of a config, or None (the full map or the cull)


def search_plan(cfg: RcmGridConfig) -> SearchPlan | None:
    """An optimiser's space: the grid's x and z ranges as continuous bounds (m)."""
    spec = optimiser(cfg)
    if spec is None:
        return None
    g = cfg.candidates.grid
    return SearchPlan(spec, {"x_rcm_m": (g.x_min_m, g.x_max_m), "z_rcm_m": (g.z_min_m, g.z_max_m)},
                      objectives_of(spec, OBJECTIVE))


def candidate_xz(cfg: RcmGridConfig) -> np.ndarray:
    """(M, 2) candidate (x, z) in config coordinates, grid in x-major order (an optimiser's batch: its points)."""
    spec = optimiser(cfg)
    if spec is not None and spec.points is not None:
        return np.asarray(spec.points, dtype=np.float64).reshape(-1, 2)
    c = cfg.candidates
    if c.list_m is not None:
        return np.asarray(c.list_m, dtype=np.float64).reshape(-1, 2)
    g = c.grid
    xs = np.linspace(g.x_min_m, g.x_max_m, g.x_count)
    zs = np.linspace(g.z_min_m, g.z_max_m, g.z_count)
    X, Z = np.meshgrid(xs, zs, indexing="ij")
    return np.stack([X.ravel(), Z.ravel()], axis=1)


def candidate_rcms(cfg: RcmGridConfig, xz: np.ndarray) -> np.ndarray:
    """(M, 3) RCM positions in the base frame (z shifted by d1 when shoulder-relative)."""
    dz = cfg.robot.link_d1_m if cfg.candidates.z_reference == "shoulder" else 0.0
    out = np.zeros((xz.shape[0], 3))
    out[:, 0] = xz[:, 0]
    out[:, 2] = xz[:, 1] + dz
    return out


def workspace_offsets(ws: Workspace) -> np.ndarray:
    """(P, 3) tip positions relative to the RCM: the cube grid of Sec. III-B."""
    n = ws.points_per_side
    t = np.linspace(-ws.cube_side_m / 2, ws.cube_side_m / 2, n) if n > 1 else np.zeros(1)
    t = 0.5 * (t - t[::-1])  # exactly symmetric about 0, so the kernel can use the mirror symmetry in y
    X, Y, Z = np.meshgrid(t, t, t - ws.depth_below_rcm_m, indexing="ij")
    return np.ascontiguousarray(np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1))


def arm_model(cfg: RcmGridConfig):
    """The kernels' ``Pa10Arm`` for this config."""
    from surgopt.kinematics.pa10_rcm import Pa10Arm

    r = cfg.robot
    lim = r.joint_limit_deg
    spd = r.max_joint_speed_rad_s
    names = pa10_7c.ACTIVE_JOINTS
    cos_limit = np.array([math.cos(min(math.radians(getattr(lim, j)), math.pi)) for j in names])
    qdot = np.array([getattr(spd, j) for j in names], dtype=np.float64)
    links = np.array([r.link_d1_m, r.link_d3_m, r.link_d5_m])
    return Pa10Arm(links, r.tool_offset_m, 1.0 if r.elbow == "up" else -1.0, qdot, cos_limit)


# ---------------------------------------------------------------------------
# study protocol
# ---------------------------------------------------------------------------


def schema():
    import pyarrow as pa

    return pa.schema(
        [
            pa.field("candidate_id", pa.int64()),
            pa.field("x_rcm_m", pa.float64()),
            pa.field("z_rcm_m", pa.float64(), metadata={"reference": "see config candidates.z_reference"}),
            pa.field("gii", pa.float64(), metadata={"eq": "7", "unit": "1"}),
            pa.field("feasible", pa.bool_()),
            pa.field("sigma_min_m_per_s", pa.float64(),
                     metadata={"meaning": "min over workspace of the smallest singular value of the constrained, "
                                          "speed-scaled forward map (1 / sigma_max of Q^-1 J_r)"}),
            pa.field("sigma_max_m_per_s", pa.float64(),
                     metadata={"meaning": "max over workspace of the largest singular value (1 / sigma_min of Q^-1 J_r)"}),
            pa.field("n_unreachable", pa.int64()),
            pa.field("n_singular", pa.int64()),
            pa.field("points_evaluated", pa.int64()),
            pa.field("gii_is_exact", pa.bool_(),
                     metadata={"meaning": "false for candidates culled by --cull: gii is then an upper bound"}),
        ]
    )


def auto_chunk(cfg: RcmGridConfig) -> int:
    """Candidates per task: about two seconds of single-core work, and at least 32 tasks."""
    from surgopt.studies import chunk_for_seconds

    spec = optimiser(cfg)
    if spec is not None:
        return spec.batch
    m = candidate_xz(cfg).shape[0]
    return chunk_for_seconds(m, cfg.workspace.points_per_side ** 3 * NS_PER_POSE * 1e-9)


#: Time model of the estimate: ~8.5 ns per pose of the cube on one core, measured over the paper map
#: (infeasible candidates cost less, the mirror half is already in it); docs/performance.md.
NS_PER_POSE_EST = 8.5


def estimate(cfg: RcmGridConfig) -> Estimate:
    """Candidates x cube points at NS_PER_POSE_EST (--cull: about a tenth of that); a row is ~75 bytes."""
    spec = optimiser(cfg)
    m = spec.trials if spec is not None else candidate_xz(cfg).shape[0]
    p = cfg.workspace.points_per_side ** 3
    seconds = m * p * NS_PER_POSE_EST * 1e-9 * (0.1 if cfg.search == "cull" else 1.0)
    return Estimate(items=m, what="RCM candidates", rows=m, seconds_one_core=seconds,
                    peak_bytes=peak_bytes(m, 75, working_bytes=m * 64 + p * 200))


def n_tasks(cfg: RcmGridConfig, chunk: int) -> int:
    if cfg.search == "cull":
        return 1
    spec = optimiser(cfg)
    if spec is not None:
        return math.ceil(spec.trials / spec.batch)
    return max(1, math.ceil(candidate_xz(cfg).shape[0] / chunk))


def warm_up(cfg: RcmGridConfig) -> None:
    """Compile (or load from the on-disk cache) the kernels in the parent."""
    from surgopt.kinematics import pa10_rcm as k

    arm = arm_model(cfg)
    rcm = np.array([[0.5, 0.0, 0.1]])
    off = np.array([[0.0, 0.0, -0.1]])
    k.rcm_candidates_extremes(rcm, off, arm)
    if cfg.search == "cull":
        k.rcm_candidate_bounded(rcm[0], off, arm, 0.0, 64)


def _rows(ids, xz, lo, hi, n_unr, n_sing, n_eval, exact):
    feasible = n_unr == 0
    gii = global_isotropy_index(lo, hi, feasible)
    return {
        "candidate_id": ids.astype(np.int64),
        "x_rcm_m": xz[:, 0].copy(),
        "z_rcm_m": xz[:, 1].copy(),
        "gii": gii,
        "feasible": feasible,
        "sigma_min_m_per_s": np.where(np.isfinite(lo), lo, 0.0),
        "sigma_max_m_per_s": hi,
        "n_unreachable": n_unr.astype(np.int64),
        "n_singular": n_sing.astype(np.int64),
        "points_evaluated": n_eval.astype(np.int64),
        "gii_is_exact": exact,
    }


def compute_task(cfg: RcmGridConfig, chunk: int, index: int) -> dict:
    """Rows for candidates [index*chunk, (index+1)*chunk) (full map), or the cull search."""
    if cfg.search == "cull":
        return cull_search(cfg)
    from surgopt.kinematics.pa10_rcm import rcm_candidates_extremes

    xz_all = candidate_xz(cfg)
    if optimiser(cfg) is not None:  # one batch of trials: ids are the trial numbers
        ids, xz = index * chunk + np.arange(xz_all.shape[0]), xz_all
    else:
        ids = np.arange(index * chunk, min(xz_all.shape[0], (index + 1) * chunk))
        xz = xz_all[ids]
    offsets = workspace_offsets(cfg.workspace)
    lo, hi, n_unr, n_sing = rcm_candidates_extremes(candidate_rcms(cfg, xz), offsets, arm_model(cfg))
    n_eval = np.full(ids.shape[0], offsets.shape[0])
    return _rows(ids, xz, lo, hi, n_unr, n_sing, n_eval, np.ones(ids.shape[0], bool))


#: Points per culling block: small enough to stop early, large enough to vectorise.
CULL_BLOCK = 128


def cull_search(cfg: RcmGridConfig) -> dict:
    """Exact argmax of the GII with the Culling algorithm of Stocco & Salcudean.

    1. Every candidate is evaluated on the 27 points {first, middle, last}^3 of
       the workspace grid: a GII over a subset bounds the full GII from above.
    2. Candidates are visited by decreasing bound. Each is evaluated on the
       full workspace, corner-most points first, and dropped as soon as its
       running bound falls to the best GII found so far. Once a candidate's
       subset bound is at or below the best, all later ones are culled too.
    Rows: every candidate, ``gii_is_exact`` false where culled (gii is then
    the upper bound reached when it was dropped).
    """
    from surgopt.kinematics.pa10_rcm import (
        rcm_candidate_bounded,
        rcm_candidates_extremes,
    )

    xz = candidate_xz(cfg)
    rcms = candidate_rcms(cfg, xz)
    arm = arm_model(cfg)
    n = cfg.workspace.points_per_side
    offsets = workspace_offsets(cfg.workspace)
    # worst points first: corners, then edges, faces, centre
    radius = np.abs(offsets - offsets.mean(axis=0)).sum(axis=1)
    order = np.argsort(-radius, kind="stable")
    offsets_sorted = np.ascontiguousarray(offsets[order])
    pick = sorted({0, n // 2, n - 1})
    sub = np.array([(i * n + j) * n + k for i in pick for j in pick for k in pick])
    lo, hi, n_unr, n_sing = rcm_candidates_extremes(rcms, offsets[sub], arm)
    ub = global_isotropy_index(lo, hi, n_unr == 0)
    n_eval = np.full(xz.shape[0], sub.shape[0])
    exact = np.zeros(xz.shape[0], bool)
    best = 0.0
    for i in np.argsort(-ub, kind="stable"):
        if n_unr[i] > 0:
            exact[i] = True  # infeasible, known exactly
            continue
        if ub[i] <= best:
            continue
        r = rcm_candidate_bounded(rcms[i], offsets_sorted, arm, best, CULL_BLOCK)
        lo[i], hi[i], n_unr[i], n_sing[i], n_eval[i] = r
        if n_eval[i] == offsets.shape[0] and n_unr[i] == 0:
            exact[i] = True
            best = max(best, float(global_isotropy_index(lo[i], hi[i])))
        elif n_unr[i] > 0:
            exact[i] = True
    return _rows(np.arange(xz.shape[0]), xz, lo, hi, n_unr, n_sing, n_eval, exact)


def summary(parts) -> Summary:
    """Feasible count, the best candidate whose GII is exact, and the five best such candidates
    (``parts``: a ``surgopt.parts.Parts``, read part by part)."""
    n = parts.num_rows
    feasible = parts.count(lambda t: t["feasible"], columns=["feasible"])
    counts = {"feasible": feasible, "infeasible": n - feasible}
    headline = {"candidates": n, "feasible": feasible}
    top = parts.top("gii", 5, where=lambda t: t["gii_is_exact"])
    if top.num_rows:
        headline.update({f"best_{k}": top[k][0].as_py() for k in ("x_rcm_m", "z_rcm_m", "gii")})
    rows = [[f"{x:.3f}", f"{z:.3f}", f"{g:.5f}"] for x, z, g in
            zip(top["x_rcm_m"].to_pylist(), top["z_rcm_m"].to_pylist(), top["gii"].to_pylist())]
    return Summary(headline, counts, [("best RCM candidates", ["x_rcm_m", "z_rcm_m", "gii"], rows)])


def feasible_mask(table):
    return table["feasible"].to_numpy(zero_copy_only=False)


STUDY = Study(
    name=NAME, kernel_version=KERNEL_VERSION, config_model=RcmGridConfig, default_config=DEFAULT_CONFIG,
    help=HELP, config_help=CONFIG_HELP, schema=schema, key_columns=KEY_COLUMNS, objective=OBJECTIVE,
    auto_chunk=auto_chunk, n_tasks=n_tasks, warm_up=warm_up, compute_task=compute_task, summary=summary,
    feasible_mask=feasible_mask, figures=figures_in("rcm_grid"), estimate=estimate, search_plan=search_plan,
    flags=(Flag("--cull", "Fast exact argmax with the Culling algorithm (Stocco & Salcudean) instead of "
                          "the full GII map; culled candidates carry an upper bound.",
                config_update={"search": "cull"}),))
