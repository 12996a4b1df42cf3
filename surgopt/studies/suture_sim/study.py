"""Study ``suture-sim``: one throat-robot arm suturing with weighted least-norm redundancy resolution.

Wei, Xu & Simaan (throat slave): the 8 inputs [q1, q2, q3, q4, theta_L,
delta, phi_L', psi] drive the 6-DoF gripper pose (eq. 30); eq. 32 resolves
the redundancy with a diagonal weight W. Every combination of weight set,
snake-arm length, fulcrum position, task mode, suture radius and speed is one
run (one task); rows are the time steps of every run. One module (~440 lines): the declaration, its
rows and the paper's summary read one another's columns (the study's one folder holds the rest).
"""
from __future__ import annotations

import math
from typing import Annotated, Literal

import numpy as np
from pydantic import Field, model_validator

from surgopt.config import StrictModel
from surgopt.robots.throat_arm import MODE_NAMES, SutureMode
from surgopt.robots import throat_arm as arm
from surgopt.studies.suture_sim import HELP  # the command's help, read by the CLI without importing this module
from surgopt.studies import Estimate, Study, Summary, figures_in, html_views_in, peak_bytes

NAME = "suture-sim"
CONFIG_HELP = ("TOML or YAML config. Without it: the paper's suturing simulation (W1 and W2, 550 and 800 mm "
             "arms, 6 mm half circle at 0.5 mm/s, dt 0.01 s).")
KERNEL_VERSION = "throat-2"  # 2: per-joint range margins stored with every step
DEFAULT_CONFIG = "suture_wei_xu_simaan.toml"
OBJECTIVE = None  # runs are compared side by side, not ranked
KEY_COLUMNS = ("run_id", "step")

JOINT_COLUMNS = ("q1_rad", "q2_rad", "q3_mm", "q4_rad", "q5_rad", "q6_rad", "q7_rad", "q8_rad")
NORM_COLUMNS = tuple(f"q{i}_norm" for i in range(1, 9))
#: min(q - lower, upper - q) of each joint at each step, in the joint's unit: negative beyond its range.
MARGIN_COLUMNS = tuple(c.replace("_rad", "_margin_rad").replace("_mm", "_margin_mm") for c in JOINT_COLUMNS)

Positive = Annotated[float, Field(gt=0)]


class FiveBar(StrictModel):
    """Table I of the paper; l1 ground link, l5/l2 actuated, l4/l3 distal, l6 extension of l3."""

    l1_mm: Positive = arm.FIVE_BAR_LINKS_MM[0]
    l2_mm: Positive = arm.FIVE_BAR_LINKS_MM[1]
    l3_mm: Positive = arm.FIVE_BAR_LINKS_MM[2]
    l4_mm: Positive = arm.FIVE_BAR_LINKS_MM[3]
    l5_mm: Positive = arm.FIVE_BAR_LINKS_MM[4]
    l6_mm: Positive = arm.FIVE_BAR_LINKS_MM[5]
    branch: Literal["left", "right"] = arm.FIVE_BAR_BRANCH


class StartPose(StrictModel):
    """Start pose of Sec. V-B: [1.4522, 2.4707, 50, 0, pi/2, -pi/3, 0, -pi/3]."""

    q1_rad: float = arm.START_POSE[0]
    q2_rad: float = arm.START_POSE[1]
    q3_mm: float = arm.START_POSE[2]
    q4_rad: float = arm.START_POSE[3]
    theta_L_rad: float = arm.START_POSE[4]
    delta_rad: float = arm.START_POSE[5]
    phi_L_rad: float = arm.START_POSE[6]
    psi_rad: float = arm.START_POSE[7]


Range = Annotated[list[float], Field(min_length=2, max_length=2)]


class JointRange(StrictModel):
    """Each joint's [lower, upper] (rad; q3 mm): the limit check (the robot file's JOINT_RANGES)."""

    q1_rad: Range = list(arm.JOINT_RANGES[0])
    q2_rad: Range = list(arm.JOINT_RANGES[1])
    q3_mm: Range = list(arm.JOINT_RANGES[2])
    q4_rad: Range = list(arm.JOINT_RANGES[3])
    theta_L_rad: Range = list(arm.JOINT_RANGES[4])
    delta_rad: Range = list(arm.JOINT_RANGES[5])
    phi_L_rad: Range = list(arm.JOINT_RANGES[6])
    psi_rad: Range = list(arm.JOINT_RANGES[7])

    @model_validator(mode="after")
    def _ordered(self):
        for name, (lo, hi) in self:
            if not lo <= hi:
                raise ValueError(f"{name}: [{lo:g}, {hi:g}] has lower > upper")
        return self


class JointMax(StrictModel):
    """q_imax of the paper's normalisation |q_i / q_imax| (Fig. 7); the limit check uses ``joint_range``."""

    q1_rad: Positive = arm.Q_MAX[0]
    q2_rad: Positive = arm.Q_MAX[1]
    q3_mm: Positive = arm.Q_MAX[2]
    q4_rad: Positive = arm.Q_MAX[3]
    theta_L_rad: Positive = arm.Q_MAX[4]
    delta_rad: Positive = arm.Q_MAX[5]
    phi_L_rad: Positive = arm.Q_MAX[6]
    psi_rad: Positive = arm.Q_MAX[7]


class Robot(StrictModel):
    five_bar: FiveBar = FiveBar()
    slu_length_mm: Positive = arm.SLU_LENGTH_MM
    pmu_length_mm: Positive = arm.PMU_LENGTH_MM
    start_pose: StartPose = StartPose()
    joint_max: JointMax = JointMax()
    joint_range: JointRange = JointRange()

    @model_validator(mode="after")
    def _five_bar_closes_at_the_start_pose(self):
        """|B - D| must lie in [|l4 - l3|, l3 + l4] for the distal links to meet (eqs. 3-5)."""
        fb, s = self.five_bar, self.start_pose
        dx = fb.l2_mm * math.sin(s.q2_rad) - fb.l5_mm * math.sin(s.q1_rad)
        dy = fb.l2_mm * math.cos(s.q2_rad) + fb.l1_mm / 2 - (fb.l5_mm * math.cos(s.q1_rad) - fb.l1_mm / 2)
        d = math.hypot(dx, dy)
        if abs(fb.l4_mm - fb.l3_mm) <= d <= fb.l3_mm + fb.l4_mm:
            crossing = five_bar_crossing(fb, s.q1_rad, s.q2_rad)
            if crossing:
                raise ValueError(f"five_bar.branch: {fb.branch!r} assembles the five-bar at the start pose as a crossed "
                                 f"(self-intersecting) pentagon: {crossing}; no physical five-bar is built that way "
                                 f"(use the other branch)")
        if not abs(fb.l4_mm - fb.l3_mm) <= d <= fb.l3_mm + fb.l4_mm:
            raise ValueError(f"the five-bar cannot close at the start pose: its actuated links' ends are {d:.1f} mm "
                             f"apart, the distal links l3, l4 reach {abs(fb.l4_mm - fb.l3_mm):g} to "
                             f"{fb.l3_mm + fb.l4_mm:g} mm (change robot.five_bar or robot.start_pose q1_rad, q2_rad)")
        return self


def five_bar_pentagon(fb: FiveBar, q1: float, q2: float) -> list:
    """The five-bar's joints A1 (q1's actuator), D, C, B, A2 (q2's actuator) in the base plane (eqs. 3-5;
    C on the side of D -> B that ``fb.branch`` names), or [] when the loop cannot close."""
    a1, a2 = np.array([0.0, -fb.l1_mm / 2]), np.array([0.0, fb.l1_mm / 2])
    D = np.array([fb.l5_mm * math.sin(q1), fb.l5_mm * math.cos(q1) - fb.l1_mm / 2])
    B = np.array([fb.l2_mm * math.sin(q2), fb.l2_mm * math.cos(q2) + fb.l1_mm / 2])
    e = B - D
    d = float(np.hypot(*e))
    a = (fb.l4_mm ** 2 - fb.l3_mm ** 2 + d * d) / (2 * d)
    if fb.l4_mm ** 2 < a * a:
        return []
    h = math.sqrt(fb.l4_mm ** 2 - a * a)
    eh = e / d
    C = D + a * eh + (1.0 if fb.branch == "left" else -1.0) * h * np.array([-eh[1], eh[0]])
    return [a1, D, C, B, a2]


def _segments_cross(p, q, r, s) -> bool:
    """Whether segments pq and rs cross at a point inside both (orientation test)."""
    def orient(a, b, c):
        return np.sign((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))

    return orient(p, q, r) * orient(p, q, s) < 0 and orient(r, s, p) * orient(r, s, q) < 0


def five_bar_crossing(fb: FiveBar, q1: float, q2: float) -> str:
    """'' for a simple pentagon A1-D-C-B-A2, else which two of its edges cross."""
    names = ["A1", "D", "C", "B", "A2"]
    pts = five_bar_pentagon(fb, q1, q2)
    if not pts:
        return ""
    for i in range(5):
        for j in range(i + 2, 5):
            if (i, j) == (0, 4):
                continue
            if _segments_cross(pts[i], pts[(i + 1) % 5], pts[j], pts[(j + 1) % 5]):
                return f"edge {names[i]}-{names[(i + 1) % 5]} crosses edge {names[j]}-{names[(j + 1) % 5]}"
    return ""


#: A run's time steps at most (one run is one task, held in memory while it runs).
MAX_STEPS_PER_RUN = 1_000_000
#: Runs a config may name at most: each run is one task and one stored part (the paper's grid is 16).
MAX_RUNS = 10_000


class Task(StrictModel):
    modes: list[Literal[MODE_NAMES]] = Field(["spin"], min_length=1)
    radius_mm: list[Positive] = Field([6.0], min_length=1)
    speed_mm_s: list[Positive] = Field([0.5], min_length=1)
    arc_deg: float = Field(180.0, gt=0, le=360)
    dt_s: float = Field(0.01, gt=0, le=1)
    gain: float = Field(1.0, gt=0, le=1, description="closed-loop correction per step")
    damping: float = Field(0.0, ge=0, description="weighted damped least squares; 0 = eq. 32 exactly")

    @model_validator(mode="after")
    def _not_too_long(self):
        """The longest run (the largest radius at the least speed), by arithmetic: a list of thousands of radii
        and speeds is not walked pair by pair to find it."""
        r, v = max(self.radius_mm), min(self.speed_mm_s)
        steps = math.radians(self.arc_deg) * r / v / self.dt_s
        if steps > MAX_STEPS_PER_RUN:
            raise ValueError(f"radius {r} mm at {v} mm/s with dt {self.dt_s} s is {steps:.0f} steps (max 1e6)")
        return self


WeightVector = Annotated[list[Annotated[float, Field(gt=0)]], Field(min_length=8, max_length=8)]


class SutureSimConfig(StrictModel):
    robot: Robot = Robot()
    task: Task = Task()
    weights: dict[str, WeightVector] = Field(
        default_factory=lambda: {"W1": [1.0] * 8, "W2": [1000.0, 1000.0] + [0.1] * 6}, min_length=1)
    arm_length_mm: list[Positive] = Field(list(arm.SNAKE_ARM_LENGTHS_MM), min_length=1)
    fulcrum_to_tip_mm: list[Positive] = Field([arm.FULCRUM_TO_TIP_MM], min_length=1)

    @model_validator(mode="after")
    def _fulcrum_inside_arm(self):
        """The longest fulcrum-to-tip against the shortest holder (the pair that fails first), by arithmetic."""
        la, f = min(self.arm_length_mm), max(self.fulcrum_to_tip_mm)
        if f >= la + self.robot.start_pose.q3_mm:
            raise ValueError(f"fulcrum_to_tip_mm {f} must be shorter than the holder ({la} mm + q3)")
        return self

    @model_validator(mode="after")
    def _runs_bounded(self):
        """The run grid counted by arithmetic (the product of the lists' lengths) and refused past MAX_RUNS."""
        n = math.prod(len(v) for v in _run_axes(self))
        if n > MAX_RUNS:
            sizes = " x ".join(f"{name} {len(v)}" for name, v in zip(RUN_AXES, _run_axes(self)))
            raise ValueError(f"{sizes} make {n:,} runs, more than the {MAX_RUNS:,} a config may name "
                             "(each run is one task and one stored part); shorten the lists")
        return self


Config = SutureSimConfig

#: The run grid's axes, in the order runs are numbered.
RUN_AXES = ("weights", "arm_length_mm", "fulcrum_to_tip_mm", "task.modes", "task.radius_mm", "task.speed_mm_s")


def _run_axes(cfg) -> tuple[list, ...]:
    t = cfg.task
    return (list(cfg.weights.items()), cfg.arm_length_mm, cfg.fulcrum_to_tip_mm, t.modes, t.radius_mm, t.speed_mm_s)


def n_runs(cfg: SutureSimConfig) -> int:
    """Runs of the config's grid: the product of its lists' lengths."""
    return math.prod(len(v) for v in _run_axes(cfg))


def run_at(cfg: SutureSimConfig, index: int) -> dict:
    """Run ``index`` of the grid in ``itertools.product`` order (weights, arm length, fulcrum, mode, radius,
    speed; the last fastest), without listing the others."""
    axes = _run_axes(cfg)
    (w, wv), la, f, m, r, v = (axis[k] for axis, k in zip(axes, np.unravel_index(index, [len(a) for a in axes])))
    return dict(run_id=index, weight_set=w, weights=np.array(wv), arm_length_mm=la, fulcrum_to_tip_mm=f,
                mode=m, radius_mm=r, speed_mm_s=v)


def run_grid(cfg: SutureSimConfig) -> list[dict]:
    """Every combination, in a fixed order: one dict per run (at most MAX_RUNS)."""
    return [run_at(cfg, i) for i in range(n_runs(cfg))]


def start_q(cfg: SutureSimConfig) -> np.ndarray:
    s = cfg.robot.start_pose
    return np.array([s.q1_rad, s.q2_rad, s.q3_mm, s.q4_rad, s.theta_L_rad, s.delta_rad, s.phi_L_rad, s.psi_rad])


def joint_ranges(cfg: SutureSimConfig) -> np.ndarray:
    """8 x 2: each joint's [lower, upper]."""
    return np.array([v for _, v in cfg.robot.joint_range], float)


def q_max(cfg: SutureSimConfig) -> np.ndarray:
    m = cfg.robot.joint_max
    return np.array([m.q1_rad, m.q2_rad, m.q3_mm, m.q4_rad, m.theta_L_rad, m.delta_rad, m.phi_L_rad, m.psi_rad])


def geometry(cfg: SutureSimConfig, arm_length_mm: float, fulcrum_to_tip_mm: float):
    """The kernel's ``ThroatGeometry``; P_F on the arm axis (straight down at the start pose)."""
    from surgopt.kinematics.throat import ThroatGeometry, five_bar

    fb = cfg.robot.five_bar
    geo = ThroatGeometry(fb.l1_mm, fb.l2_mm, fb.l3_mm, fb.l4_mm, fb.l5_mm, fb.l6_mm, float(arm_length_mm),
                         cfg.robot.slu_length_mm, cfg.robot.pmu_length_mm, np.zeros(3),
                         1.0 if fb.branch == "left" else -1.0)
    q0 = start_q(cfg)
    P_U = five_bar(q0[0], q0[1], geo)[0]
    if not np.all(np.isfinite(P_U)):
        from surgopt.errors import ConfigError

        raise ConfigError("config", "the five-bar cannot close at the start pose", "robot.start_pose")
    return geo._replace(fulcrum_mm=np.array([P_U[0], P_U[1], -(arm_length_mm + q0[2] - fulcrum_to_tip_mm)]))


def schema():
    import pyarrow as pa

    fields = [pa.field("run_id", pa.int64()), pa.field("weight_set", pa.string()),
              pa.field("arm_length_mm", pa.float64()), pa.field("fulcrum_to_tip_mm", pa.float64()),
              pa.field("mode", pa.string()), pa.field("radius_mm", pa.float64()),
              pa.field("speed_mm_s", pa.float64()), pa.field("step", pa.int64()), pa.field("t_s", pa.float64())]
    fields += [pa.field(c, pa.float64()) for c in JOINT_COLUMNS + NORM_COLUMNS]
    fields += [pa.field(c, pa.float64(), metadata={"meaning": "min(q - lower, upper - q): negative beyond the "
                                                              "joint's range (robot.joint_range)"})
               for c in MARGIN_COLUMNS]
    fields += [pa.field("pos_err_mm", pa.float64()), pa.field("rot_err_deg", pa.float64()),
               pa.field("run_completed", pa.bool_(), metadata={
                   "meaning": "false: the run stopped where J W^-1 J^T became singular (set task.damping > 0)"})]
    return pa.schema(fields)


#: Cost model: one weighted least-norm step with FK, Jacobian and 8x6 solve, ~14 us on one core
#: (docs/performance.md: 73,000 steps/s); a stored step is ~220 bytes.
US_PER_STEP = 14.0


def run_steps(cfg: SutureSimConfig, run: dict) -> int:
    """Time steps of one run: round(arc * radius / (speed * dt)), plus the start row."""
    t = cfg.task
    return int(np.round(math.radians(t.arc_deg) * run["radius_mm"] / run["speed_mm_s"] / t.dt_s)) + 1


def total_steps(cfg: SutureSimConfig) -> int:
    """Time steps of every run, by arithmetic: each (radius, speed) pair's steps (run_steps) times the runs
    that share it."""
    t = cfg.task
    r, v = np.asarray(t.radius_mm, float)[:, None], np.asarray(t.speed_mm_s, float)[None, :]
    per_pair = np.round(math.radians(t.arc_deg) * r / v / t.dt_s).astype(np.int64) + 1
    return int(per_pair.sum()) * (n_runs(cfg) // per_pair.size)


def estimate(cfg: SutureSimConfig) -> Estimate:
    steps = total_steps(cfg)
    return Estimate(steps, "time steps", steps, steps * US_PER_STEP * 1e-6, peak_bytes(steps, 220))


def auto_chunk(cfg: SutureSimConfig) -> int:
    """One run per task (a paper run is ~0.05 s; runs are the natural unit of resumption)."""
    return 1


def n_tasks(cfg: SutureSimConfig, chunk: int) -> int:
    return n_runs(cfg)


def warm_up(cfg: SutureSimConfig) -> None:
    from surgopt.kinematics.throat import suture_run

    geo = geometry(cfg, cfg.arm_length_mm[0], cfg.fulcrum_to_tip_mm[0])
    suture_run(start_q(cfg), geo, np.ones(8), 0, 6.0, 600.0, math.pi, 0.01, 1.0, 0.0)


def compute_task(cfg: SutureSimConfig, chunk: int, index: int) -> dict:
    """All time steps of run ``index``."""
    from surgopt.kinematics.throat import suture_run

    run = run_at(cfg, index)
    t = cfg.task
    geo = geometry(cfg, run["arm_length_mm"], run["fulcrum_to_tip_mm"])
    ts, qs, pe, re = suture_run(start_q(cfg), geo, run["weights"], int(SutureMode[run["mode"].upper()]), run["radius_mm"],
                                run["speed_mm_s"], math.radians(t.arc_deg), t.dt_s, t.gain, t.damping)
    n = ts.shape[0]
    cols = {"run_id": np.full(n, run["run_id"], np.int64), "weight_set": [run["weight_set"]] * n,
            "arm_length_mm": np.full(n, run["arm_length_mm"]), "fulcrum_to_tip_mm": np.full(n, run["fulcrum_to_tip_mm"]),
            "mode": [run["mode"]] * n, "radius_mm": np.full(n, run["radius_mm"]),
            "speed_mm_s": np.full(n, run["speed_mm_s"]), "step": np.arange(n, dtype=np.int64), "t_s": ts}
    qn = np.abs(qs / q_max(cfg))
    rng = joint_ranges(cfg)
    margin = np.minimum(qs - rng[:, 0], rng[:, 1] - qs)
    for i, c in enumerate(JOINT_COLUMNS):
        cols[c] = qs[:, i].copy()
        cols[NORM_COLUMNS[i]] = qn[:, i].copy()
    for i, c in enumerate(MARGIN_COLUMNS):
        cols[c] = margin[:, i].copy()
    cols["pos_err_mm"] = pe
    cols["rot_err_deg"] = re
    cols["run_completed"] = np.full(n, n == run_steps(cfg, run))
    return cols


RUN_KEYS = ["run_id", "weight_set", "arm_length_mm", "fulcrum_to_tip_mm", "mode", "radius_mm", "speed_mm_s"]


def run_summary(parts):
    """One row per run: each joint's range, peak |q/q_max| and least margin to its own [lower, upper] range,
    the steps beyond a range (limit violations), max tracking errors.

    ``parts``: a ``Parts`` (each stored part holds whole runs: one run per task) or one table.
    """
    import pandas as pd

    from surgopt.parts import Parts

    if not isinstance(parts, Parts):
        return _run_summary(parts)
    return pd.concat([_run_summary(t) for t in parts]).sort_values("run_id").reset_index(drop=True)


def _run_summary(table):
    df = table.to_pandas()
    g = df.groupby("run_id", sort=True)
    out = g[RUN_KEYS[1:]].first()
    for c, nc, mc in zip(JOINT_COLUMNS, NORM_COLUMNS, MARGIN_COLUMNS):
        out[f"{c}_range"] = g[c].max() - g[c].min()
        out[f"{nc}_peak"] = g[nc].max()
        out[f"{mc}_min"] = g[mc].min()
    out["limit_violations"] = (df[list(MARGIN_COLUMNS)] < 0.0).any(axis=1).groupby(df["run_id"]).sum()
    out["max_pos_err_mm"] = g["pos_err_mm"].max()
    out["max_rot_err_deg"] = g["rot_err_deg"].max()
    out["steps"] = g.size() - 1
    out["stopped_early"] = ~g["run_completed"].first()
    return out.reset_index()


def summary(parts) -> Summary:
    """Runs within the joint limits, the worst tracking errors, and the joint ranges of the weight
    sets side by side (Fig. 7's comparison), one table per other setting."""
    s = run_summary(parts)
    ok = int(((s["limit_violations"] == 0) & ~s["stopped_early"]).sum())
    headline = {"runs": len(s), "steps_total": int(s["steps"].sum()),
                "max_pos_err_mm": float(s["max_pos_err_mm"].max()),
                "max_rot_err_deg": float(s["max_rot_err_deg"].max()),
                "runs_with_limit_violations": int((s["limit_violations"] > 0).sum()),
                "runs_stopped_at_a_singularity": int(s["stopped_early"].sum())}
    out = []
    others = ["arm_length_mm", "fulcrum_to_tip_mm", "mode", "radius_mm", "speed_mm_s"]
    for key, grp in s.groupby(others, sort=False):
        header = (["joint"] + [f"{w} range" for w in grp["weight_set"]] + [f"{w} peak |q/qmax|" for w in grp["weight_set"]]
                  + [f"{w} least margin" for w in grp["weight_set"]])
        rows = []
        for c, nc, mc in zip(JOINT_COLUMNS, NORM_COLUMNS, MARGIN_COLUMNS):
            rows.append([c] + [f"{v:.4g}" for v in grp[f"{c}_range"]] + [f"{v:.3f}" for v in grp[f"{nc}_peak"]]
                        + [f"{v:.4g}" + (" BEYOND" if v < 0 else "") for v in grp[f"{mc}_min"]])
        rows.append(["max pos err (mm)"] + [f"{v:.2e}" for v in grp["max_pos_err_mm"]] + [""] * 2 * len(grp))
        rows.append(["max rot err (deg)"] + [f"{v:.2e}" for v in grp["max_rot_err_deg"]] + [""] * 2 * len(grp))
        title = "joint ranges: arm {} mm, fulcrum {} mm before the tip, {}, r {} mm, {} mm/s".format(*key)
        out.append((title, header, rows))
    return Summary(headline, {"runs_within_limits": ok, "runs_violating_or_stopped": len(s) - ok}, out)


def feasible_mask(table):
    """Rows of runs that stayed within the joint limits and completed."""
    s = run_summary(table)
    good = set(s["run_id"][(s["limit_violations"] == 0) & ~s["stopped_early"]])
    return np.isin(table["run_id"].to_numpy(), list(good))


STUDY = Study(
    html_views=html_views_in("surgopt.studies.suture_sim.html"),
    name=NAME, kernel_version=KERNEL_VERSION, config_model=SutureSimConfig, default_config=DEFAULT_CONFIG,
    help=HELP, config_help=CONFIG_HELP, schema=schema, key_columns=KEY_COLUMNS, objective=OBJECTIVE,
    auto_chunk=auto_chunk, n_tasks=n_tasks, warm_up=warm_up, compute_task=compute_task, summary=summary,
    feasible_mask=feasible_mask, figures=figures_in("surgopt.studies.suture_sim.figures"), chunked=False, estimate=estimate)
