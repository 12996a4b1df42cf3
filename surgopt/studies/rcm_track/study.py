"""Study ``rcm-track``: the helical test trajectory of Locke & Patel 2007, Sec. IV (Table I's error column).

config (an rcm-grid config plus [track]) -> candidates -> chunks -> per candidate: the RCM-constrained
IK of the reference path (the serial-chain walk, ``kinematics/serial_chain``), the joint-level P
controller at the control rate (``kinematics/rcm_track``), the GII of the same candidate (rcm-grid's
kernel) -> one row per candidate, with per-step traces for the candidates in ``track.keep``.
"""
from __future__ import annotations

import math
from typing import Literal

import numpy as np
from pydantic import Field, model_validator

from surgopt.config import StrictModel
from surgopt.studies.rcm_track import HELP  # the command's help, read by the CLI without importing this module
from surgopt.studies import Estimate, Study, Summary, figures_in, html_views_in, peak_bytes
from surgopt.studies.rcm_grid import study as grid
from surgopt.studies.rcm_grid.config import RcmSetup

NAME = "rcm-track"
CONFIG_HELP = ("TOML or YAML config: any rcm-grid config, plus an optional [track] section. Without it: "
               "the paper's 15 Table I RCMs on the PA10-7C.")
#: Bump when a kernel change alters results.
KERNEL_VERSION = "rcm-track-1"
DEFAULT_CONFIG = "rcm_track_table1.toml"
OBJECTIVE = None  # compared side by side: a smaller error is better, the GII column is rcm-grid's objective
KEY_COLUMNS = ("candidate_id",)
#: Locke & Patel's Table I "Max error" (mm), in Table I's row order (rcm_grid.PAPER_TABLE_I).
PAPER_MAX_ERROR_MM = (6.3, 6.1, 6.1, 5.4, 5.3, 5.5, 5.3, 5.1, 5.2, 6.3, 5.4, 5.3, 17.1, 16.7, 16.2)
#: Proportional gain (1/s) calibrated on the paper's best candidate, (0.535, -0.210) from the shoulder:
#: 5.1 mm maximum tip error there (docs/reproduce_pa10_track.py; tests hold it).
CALIBRATED_GAIN_PER_S = 10.74
#: Per-step traces keep every this many control steps (10 ms at 1 kHz).
TRACE_EVERY_STEPS = 10


class Track(StrictModel):
    """The test trajectory and the controller (Sec. IV-A, IV-B)."""

    duration_s: float = Field(10.0, gt=0, le=600, description="time to run the whole helix")
    turns: float = Field(2.5, gt=0, le=50)
    radius_margin_m: float = Field(0.002, ge=0, le=0.5, description="helix radius = cube side / 2 - margin; "
                                                                     "height = side - 2 margin")
    time_scaling: Literal["cubic", "quintic"] = "cubic"
    control_rate_hz: float = Field(1000.0, gt=0, le=100_000)
    gain_per_s: float = Field(CALIBRATED_GAIN_PER_S, gt=0, le=1e4, description="joint-level P gain")
    velocity_lag_s: float = Field(0.0, ge=0, le=10, description="first-order lag of the joint velocity loop")
    saturate: bool = Field(True, description="clip each commanded joint velocity at its rated speed")
    saturation_speed_scale: float = Field(1.0, gt=0, le=100, description="clip at this multiple of the rated "
                                                                        "speeds (the robot's real headroom)")
    ik_every_steps: int = Field(10, ge=1, le=1000, description="reference IK every n control steps, "
                                                              "linear in between")
    keep: list[int] = Field(default_factory=list, max_length=64, description="candidate_ids with per-step traces")


class RcmTrackConfig(RcmSetup):
    track: Track = Track()

    @model_validator(mode="after")
    def _fits(self):
        t = self.track
        if t.radius_margin_m >= self.workspace.cube_side_m / 2:
            raise ValueError("track.radius_margin_m must be less than half the workspace cube's side")
        steps = t.duration_s * t.control_rate_hz
        if steps > 10_000_000:
            raise ValueError(f"track: {steps:,.0f} control steps per candidate (at most 10,000,000)")
        n = grid.candidate_count(self)
        bad = [k for k in t.keep if not 0 <= k < n]
        if bad:
            raise ValueError(f"track.keep: candidate_id {bad[0]} is not among the {n} candidates")
        return self


Config = RcmTrackConfig


# ---------------------------------------------------------------------------
# config -> arrays
# ---------------------------------------------------------------------------


def reference_path(cfg: RcmTrackConfig):
    """(t (M,), tip offsets from the RCM (M, 3), speed (M,)): the helix in the workspace cube."""
    from surgopt.kinematics.rcm_track import helix_path

    ws, t = cfg.workspace, cfg.track
    return helix_path((0.0, 0.0, -ws.depth_below_rcm_m), ws.cube_side_m, t.radius_margin_m, t.turns,
                      t.duration_s, t.control_rate_hz, t.time_scaling)


def _steps(cfg: RcmTrackConfig) -> int:
    return int(round(cfg.track.duration_s * cfg.track.control_rate_hz)) + 1


def _ik_samples(cfg: RcmTrackConfig, offsets: np.ndarray):
    """The control steps whose reference gets its own IK: every ``ik_every_steps``-th and the last (the
    path is padded with its end point so that the samples divide it evenly)."""
    every = cfg.track.ik_every_steps
    m = offsets.shape[0]
    k = math.ceil((m - 1) / every)
    idx = np.minimum(np.arange(k + 1) * every, m - 1)
    padded = np.concatenate([offsets, np.repeat(offsets[-1:], k * every + 1 - m, axis=0)])
    return np.ascontiguousarray(offsets[idx]), np.ascontiguousarray(padded), every


def schema():
    import pyarrow as pa

    f64, lst = pa.float64(), pa.list_(pa.float64())
    fields = [pa.field("candidate_id", pa.int64()), pa.field("x_rcm_m", f64), pa.field("y_rcm_m", f64),
              pa.field("z_rcm_m", f64, metadata={"reference": "see config candidates.z_reference"}),
              pa.field("gii", f64, metadata={"eq": "7", "meaning": "rcm-grid's GII of this candidate"}),
              pa.field("feasible", pa.bool_(), metadata={"meaning": "the whole path reachable within the limits"}),
              pa.field("max_tip_error_mm", f64), pa.field("mean_tip_error_mm", f64),
              pa.field("max_rcm_error_mm", f64, metadata={"meaning": "distance of the RCM from the tool line"}),
              pa.field("mean_rcm_error_mm", f64)]
    fields += [pa.field(f"peak_qdot_ratio_{i + 1}", f64, metadata={"meaning": f"max |qdot|/qdot_max of active joint {i + 1}"})
               for i in range(5)]
    fields += [pa.field("saturated_s", f64, metadata={"meaning": "time with any joint at its rated speed"})]
    fields += [pa.field(f"trace_{c}", lst) for c in
               ("t_s", "tip_x_m", "tip_y_m", "tip_z_m", "tip_error_mm", "rcm_error_mm")]
    return pa.schema(fields)


#: Cost model (one core): ~1 us per reference IK point, ~0.15 us per control step (benchmarks/bench_track.py).
US_PER_IK_POINT = 1.0
US_PER_STEP = 0.15


def _seconds_per_candidate(cfg: RcmTrackConfig) -> float:
    m = _steps(cfg)
    return (m / cfg.track.ik_every_steps * US_PER_IK_POINT + m * US_PER_STEP) * 1e-6 \
        + cfg.workspace.points_per_side ** 3 * grid.ns_per_pose(cfg) * 1e-9


def auto_chunk(cfg: RcmTrackConfig) -> int:
    from surgopt.studies import chunk_for_seconds

    return chunk_for_seconds(grid.candidate_count(cfg), _seconds_per_candidate(cfg))


def n_tasks(cfg: RcmTrackConfig, chunk: int) -> int:
    return max(1, math.ceil(grid.candidate_count(cfg) / chunk))


def estimate(cfg: RcmTrackConfig) -> Estimate:
    m = grid.candidate_count(cfg)
    trace_bytes = len(cfg.track.keep) * _steps(cfg) // TRACE_EVERY_STEPS * 6 * 8
    return Estimate(items=m, what="RCM candidates", rows=m, seconds_one_core=m * _seconds_per_candidate(cfg),
                    peak_bytes=peak_bytes(m, 160, working_bytes=_steps(cfg) * 96 + trace_bytes))


def warm_up(cfg: RcmTrackConfig) -> None:
    small = cfg.model_copy(update={"track": cfg.track.model_copy(update={"duration_s": 0.01, "keep": []})})
    grid.kernel_for(cfg).warm_up(grid.workspace_offsets(cfg.workspace), cfg.workspace.points_per_side)
    chain, _, seed = cfg.robot.chain()
    path = _path(small)
    ref = _reference(small, chain, seed, grid.candidate_rcms(cfg, grid.candidate_xyz(cfg)[:1])[0], path)
    if ref is not None:
        _simulate(small, chain, ref, path, keep=True)


def _path(cfg: RcmTrackConfig):
    """(tip offsets from the RCM at every control step, the IK samples, the padded path, every): one per task."""
    _, offsets, _ = reference_path(cfg)
    ik_off, padded, every = _ik_samples(cfg, offsets)
    return offsets, ik_off, padded, every


def _reference(cfg, chain, seed, rcm, path):
    """(reference joints at the IK samples, the tip path, the RCM) of one candidate, or None when the
    path is out of reach (the serial-chain walk from the workspace centre)."""
    from surgopt.kinematics.serial_chain import rcm_walk

    offsets, ik_off, _, _ = path
    walk = rcm_walk(chain, rcm, ik_off, seed, start=np.array([0.0, 0.0, -cfg.workspace.depth_below_rcm_m]))
    if walk["n_unreachable"]:
        return None
    return walk["q"], np.ascontiguousarray(rcm + offsets), rcm


def _simulate(cfg, chain, ref, path, keep):
    """((max, mean tip error, max, mean RCM error) m, peak |qdot|/qdot_max (5,), saturated s, trace or None)."""
    from surgopt.kinematics.rcm_track import track
    from surgopt.kinematics.serial_chain import kernel_arrays

    t = cfg.track
    q_ref, p_ref, rcm = ref
    every = path[3]
    n_trace = (p_ref.shape[0] - 1) // TRACE_EVERY_STEPS + 1 if keep else 0
    trace = np.zeros((max(n_trace, 1), 6))
    e_max, e_mean, r_max, r_mean, peak, sat_s = track(
        kernel_arrays(chain), q_ref, every, p_ref, rcm, 1.0 / t.control_rate_hz, t.gain_per_s, t.velocity_lag_s,
        t.saturate, t.saturation_speed_scale, TRACE_EVERY_STEPS if keep else 0, trace)
    return (e_max, e_mean, r_max, r_mean), peak, sat_s, (trace[:n_trace] if keep else None)


def calibrate_gain(cfg: RcmTrackConfig, candidate_id: int, target_mm: float, lo: float = 0.5,
                   hi: float = 500.0) -> float:
    """The P gain (1/s) at which candidate ``candidate_id``'s maximum tip error is ``target_mm``
    (bisection in log gain: the error falls as the gain rises, until saturation). The reference IK is
    solved once; each step only re-runs the controller."""
    chain, _, seed = cfg.robot.chain()
    rcm = grid.candidate_rcms(cfg, grid.candidate_xyz(cfg)[candidate_id:candidate_id + 1])[0]
    path = _path(cfg)
    ref = _reference(cfg, chain, seed, rcm, path)
    if ref is None:
        raise ValueError(f"candidate {candidate_id} cannot follow the path")

    def error(gain):
        c = cfg.model_copy(update={"track": cfg.track.model_copy(update={"gain_per_s": gain})})
        return _simulate(c, chain, ref, path, False)[0][0] * 1e3

    for _ in range(60):
        mid = math.sqrt(lo * hi)
        if error(mid) > target_mm:
            lo = mid
        else:
            hi = mid
    return math.sqrt(lo * hi)


def compute_task(cfg: RcmTrackConfig, chunk: int, index: int) -> dict:
    xyz_all = grid.candidate_xyz(cfg)
    ids = np.arange(index * chunk, min(xyz_all.shape[0], (index + 1) * chunk))
    xyz = xyz_all[ids]
    rcms = grid.candidate_rcms(cfg, xyz)
    lo, hi, n_unr, _, _ = grid.kernel_for(cfg).extremes(rcms, grid.workspace_offsets(cfg.workspace),
                                                        cfg.workspace.points_per_side)
    chain, _, seed = cfg.robot.chain()
    path = _path(cfg)
    keep = set(cfg.track.keep)
    n = ids.shape[0]
    err = np.full((n, 4), np.nan)
    peaks = np.full((n, 5), np.nan)
    sat = np.full(n, np.nan)
    feasible = np.zeros(n, bool)
    traces = [[[] for _ in range(n)] for _ in range(6)]
    for i, (cid, rcm) in enumerate(zip(ids, rcms)):
        ref = _reference(cfg, chain, seed, rcm, path)
        if ref is None:
            continue
        e, pk, s, tr = _simulate(cfg, chain, ref, path, int(cid) in keep)
        err[i] = np.array(e) * 1e3
        peaks[i], sat[i], feasible[i] = pk, s, True
        if tr is not None:
            for c in range(6):
                traces[c][i] = (tr[:, c] * (1e3 if c >= 4 else 1.0)).tolist()
    from surgopt.metrics import global_isotropy_index

    rows = {"candidate_id": ids.astype(np.int64), "x_rcm_m": xyz[:, 0].copy(), "y_rcm_m": xyz[:, 1].copy(),
            "z_rcm_m": xyz[:, 2].copy(), "gii": global_isotropy_index(lo, hi, n_unr == 0), "feasible": feasible,
            "max_tip_error_mm": err[:, 0], "mean_tip_error_mm": err[:, 1], "max_rcm_error_mm": err[:, 2],
            "mean_rcm_error_mm": err[:, 3]}
    rows.update({f"peak_qdot_ratio_{j + 1}": peaks[:, j] for j in range(5)})
    rows["saturated_s"] = sat
    for c, name in enumerate(("t_s", "tip_x_m", "tip_y_m", "tip_z_m", "tip_error_mm", "rcm_error_mm")):
        rows[f"trace_{name}"] = traces[c]
    return rows


def rank_correlation(a, b) -> float:
    """Spearman's rho with average ranks for ties (numpy only)."""
    def ranks(x):
        x = np.asarray(x, float)
        order = np.argsort(x, kind="stable")
        r = np.empty(len(x))
        r[order] = np.arange(len(x), dtype=float)
        for v in np.unique(x):  # ties: the mean rank
            m = x == v
            r[m] = r[m].mean()
        return r

    ra, rb = ranks(a), ranks(b)
    return float(np.corrcoef(ra, rb)[0, 1])


def summary(parts) -> Summary:
    """The feasible count, the worst and best candidates by maximum tip error, and (when the candidates are
    Table I's) the rank correlation with the paper's errors."""
    cols = ["candidate_id", "x_rcm_m", "z_rcm_m", "gii", "feasible", "max_tip_error_mm", "max_rcm_error_mm",
            "saturated_s"]
    d = {c: parts.column(c) for c in cols}
    f = d["feasible"].astype(bool)
    n = len(f)
    headline = {"candidates": n, "feasible": int(f.sum())}
    rows = []
    if f.any():
        e = d["max_tip_error_mm"][f]
        headline.update({"best_max_tip_error_mm": float(e.min()), "worst_max_tip_error_mm": float(e.max()),
                         "spearman_gii_vs_error": rank_correlation(d["gii"][f], -e)})
        paper = _paper_errors(d["x_rcm_m"], d["z_rcm_m"])
        if paper is not None:
            headline["spearman_vs_paper"] = rank_correlation(paper[f], e)
        for i in np.argsort(np.where(f, d["max_tip_error_mm"], np.inf))[:15]:
            if not f[i]:
                continue
            rows.append([f"{d['x_rcm_m'][i]:.3f}", f"{d['z_rcm_m'][i]:.3f}", f"{d['gii'][i]:.4f}",
                         f"{d['max_tip_error_mm'][i]:.2f}", f"{d['max_rcm_error_mm'][i]:.2f}",
                         f"{d['saturated_s'][i]:.2f}"])
    return Summary(headline, {"feasible": int(f.sum()), "infeasible": int(n - f.sum())},
                   [("candidates by max tip error", ["x_rcm_m", "z_rcm_m", "gii", "max_tip_error_mm",
                                                     "max_rcm_error_mm", "saturated_s"], rows)])


def _paper_errors(x, z):
    """The paper's max errors for candidates that are exactly Table I's rows (x, z from the shoulder), else None."""
    paper = {(round(px, 3), round(pz, 3)): e for (px, pz, _), e in zip(grid.PAPER_TABLE_I, PAPER_MAX_ERROR_MM)}
    keys = [(round(float(a), 3), round(float(b), 3)) for a, b in zip(x, z)]
    if not keys or not all(k in paper for k in keys):
        return None
    return np.array([paper[k] for k in keys])


def feasible_mask(table):
    return table["feasible"].to_numpy(zero_copy_only=False)


STUDY = Study(
    html_views=html_views_in("surgopt.studies.rcm_grid.html"),
    name=NAME, kernel_version=KERNEL_VERSION, config_model=RcmTrackConfig, default_config=DEFAULT_CONFIG,
    help=HELP, config_help=CONFIG_HELP, schema=schema, key_columns=KEY_COLUMNS, objective=OBJECTIVE,
    auto_chunk=auto_chunk, n_tasks=n_tasks, warm_up=warm_up, compute_task=compute_task, summary=summary,
    feasible_mask=feasible_mask, feasible_columns=("feasible",), figures=figures_in("surgopt.studies.rcm_track.figures"), estimate=estimate, extends="rcm-grid",
    config_section="track")
