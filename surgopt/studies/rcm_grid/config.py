"""Config models of the ``rcm-grid`` study: the robot (a shipped model, a URDF file or an inline DH table),
the workspace cube and the RCM candidates.

A robot section is resolved once, at validation: the source is checked (the URDF parsed, the chain
reduced to five active joints, every joint name checked), and the fields the user left out are filled
from the model's defaults, so the validated config (what ``--print-config`` shows and what is hashed
into the store key) says everything, including the URDF's sha256 (editing the file misses the cache).
Without ``model``, ``urdf`` or ``dh`` the robot is the paper's PA10-7C. One module of ~450 lines:
the robot section's resolution (sources, defaults, the chain checks) is most of it and is one piece.
"""
from __future__ import annotations

import math
from typing import Annotated, ClassVar, Literal

from pydantic import Field, PrivateAttr, ValidationInfo, model_validator

from surgopt.config import NOT_IN_KEY, StrictModel
from surgopt.metrics import POSE_METRICS
from surgopt.robots import pa10_7c
from surgopt.robots.models import MODELS, get_model
from surgopt.plans.search import SearchSpec, check_objectives, search_field


def search_objectives(metric: str) -> tuple[str, ...]:
    """Row columns a [search] may optimise under this per-pose metric (its sigma columns carry its unit)."""
    return ("gii", *POSE_METRICS[metric].sigma_columns, "x_rcm_m", "y_rcm_m", "z_rcm_m")


#: Row columns a [search] may optimise (the RCM metric's).
SEARCH_OBJECTIVES = search_objectives("alternative")
#: PA10-only fields (the closed-form kernel's parameters).
PA10_FIELDS = ("link_d1_m", "link_d3_m", "link_d5_m", "link_d7_m", "tool_length_from", "elbow", "joint_limit_deg",
               "max_joint_speed_rad_s")
Finite = Annotated[float, Field(ge=-1e3, le=1e3)]


class JointLimitsDeg(StrictModel):
    """Symmetric joint ranges +-value (deg) of the PA10's five active joints [MHI]."""

    S1: float = Field(pa10_7c.JOINT_LIMIT_DEG["S1"], gt=0, le=360)
    S2: float = Field(pa10_7c.JOINT_LIMIT_DEG["S2"], gt=0, le=360)
    E1: float = Field(pa10_7c.JOINT_LIMIT_DEG["E1"], gt=0, le=360)
    E2: float = Field(pa10_7c.JOINT_LIMIT_DEG["E2"], gt=0, le=360)
    W1: float = Field(pa10_7c.JOINT_LIMIT_DEG["W1"], gt=0, le=360)


class JointSpeedsRadS(StrictModel):
    """Rated maximum speeds (rad/s) of the PA10's active joints: the diagonal of the scaling matrix Q [MHI]."""

    S1: float = Field(pa10_7c.MAX_JOINT_SPEED_RAD_S["S1"], gt=0, le=1e3)
    S2: float = Field(pa10_7c.MAX_JOINT_SPEED_RAD_S["S2"], gt=0, le=1e3)
    E1: float = Field(pa10_7c.MAX_JOINT_SPEED_RAD_S["E1"], gt=0, le=1e3)
    E2: float = Field(pa10_7c.MAX_JOINT_SPEED_RAD_S["E2"], gt=0, le=1e3)
    W1: float = Field(pa10_7c.MAX_JOINT_SPEED_RAD_S["W1"], gt=0, le=1e3)


class DhRowConfig(StrictModel):
    """One joint of an inline DH table (``[[robot.dh]]``): lengths in m, angles in degrees.

    A revolute row's limits are ``lower_deg``/``upper_deg`` (both left out: continuous) and its rated
    speed ``max_speed_rad_s``; a prismatic row (``joint = "prismatic"``) slides along d with
    ``lower_m``/``upper_m`` and ``max_speed_m_s``.
    """

    name: str | None = Field(None, min_length=1, max_length=64)
    joint: Literal["revolute", "prismatic"] = "revolute"
    a_m: Finite
    alpha_deg: Finite
    d_m: Finite
    theta_offset_deg: Finite = 0.0
    lower_deg: Finite | None = None
    upper_deg: Finite | None = None
    lower_m: Finite | None = None
    upper_m: Finite | None = None
    max_speed_rad_s: float | None = Field(None, gt=0, le=1e3)
    max_speed_m_s: float | None = Field(None, gt=0, le=1e3)

    #: whether a row must give its rated speed (rcm-grid's metric scales by it; an RCM arm's rows need none)
    speed_required: ClassVar[bool] = True

    @model_validator(mode="after")
    def _fields_of_its_kind(self):
        rev = self.joint == "revolute"
        lo, hi, speed = ("lower_deg", "upper_deg", "max_speed_rad_s") if rev else ("lower_m", "upper_m", "max_speed_m_s")
        other = ("lower_m", "upper_m", "max_speed_m_s") if rev else ("lower_deg", "upper_deg", "max_speed_rad_s")
        wrong = [f for f in other if getattr(self, f) is not None]
        if wrong:
            raise ValueError(f"a {self.joint} row takes {lo}, {hi}, {speed}, not {', '.join(wrong)}")
        if self.speed_required and getattr(self, speed) is None:
            raise ValueError(f"{speed} is required (the rated speed: the joint's entry of the scaling Q)")
        if (getattr(self, lo) is None) != (getattr(self, hi) is None):
            raise ValueError(f"give both {lo} and {hi}, or neither (unlimited)")
        if getattr(self, lo) is not None and getattr(self, lo) > getattr(self, hi):
            raise ValueError(f"{lo} must be <= {hi}")
        return self

    def row(self, index: int):
        from surgopt.robots.chain import DhRow

        rev = self.joint == "revolute"
        speed = self.max_speed_rad_s if rev else self.max_speed_m_s
        return DhRow.deg(self.a_m, self.alpha_deg, self.d_m, self.theta_offset_deg,
                         self.lower_deg if rev else self.lower_m, self.upper_deg if rev else self.upper_m,
                         1.0 if speed is None else speed, self.name or f"j{index + 1}", not rev)


class Robot(StrictModel):
    """The arm: a shipped ``model``, a ``urdf`` file, or an inline ``dh`` table (docs/robots.md)."""

    model: str | None = Field(None, description=f"a shipped model: {', '.join(MODELS)}")
    urdf: str | None = Field(None, min_length=1, description="URDF file, relative to the config file (its content "
                             "hash, urdf_sha256, is in the store key, not its path)", json_schema_extra=NOT_IN_KEY)
    base_link: str | None = Field(None, min_length=1)
    tip_link: str | None = Field(None, min_length=1)
    urdf_sha256: str | None = Field(None, description="filled in: the URDF's content hash (part of the store key)")
    dh: list[DhRowConfig] | None = Field(None, min_length=1, max_length=32)
    dh_convention: Literal["standard", "modified"] | None = None
    kernel: Literal["auto", "closed_form", "generic"] = Field(
        "auto", description="the PA10's closed-form IK (auto for pa10_7c) or the generic serial-chain Newton kernel")
    locked_joints_deg: dict[str, Finite] | None = Field(None, description="joints held fixed (deg, or m if prismatic)")
    seed_deg: dict[str, Finite] | None = Field(None, description="a configuration on the wanted IK branch")
    tool_length_m: float | None = Field(None, gt=0, le=5, description="tool tip along the tip link's z axis")
    tool_axis: list[Finite] | None = Field(None, min_length=3, max_length=3, description="in the tip link's frame")
    tool_offset_m: list[Finite] | None = Field(None, min_length=3, max_length=3,
                                               description="tool base in the tip link's frame")
    spin_joint: str | None = Field(None, description="the locked joint that only spins the tool about its own axis "
                                                     "(the standard Jacobian's sixth joint); default: the model's")
    speed_override_rad_s: dict[str, Annotated[float, Field(gt=0, le=100)]] | None = Field(
        None, description="rated speed per joint name (rad/s; m/s if prismatic), replacing the URDF's or DH "
                          "table's (e.g. a file with placeholder or zero velocities)")
    range_override_deg: dict[str, Annotated[list[Finite], Field(min_length=2, max_length=2)]] | None = Field(
        None, description="[lower, upper] per joint name (deg; m if prismatic), replacing the file's limits")
    # PA10-7C (closed-form kernel) parameters: only with model = "pa10_7c"
    link_d1_m: float | None = Field(None, gt=0, le=5, description="PA10: base to shoulder (S2 axis)")
    link_d3_m: float | None = Field(None, gt=0, le=5, description="PA10: shoulder to elbow")
    link_d5_m: float | None = Field(None, gt=0, le=5, description="PA10: elbow to wrist centre")
    link_d7_m: float | None = Field(None, ge=0, le=5, description="PA10: wrist centre to flange")
    tool_length_from: Literal["flange", "wrist_centre"] | None = None
    elbow: Literal["up", "down"] | None = None
    joint_limit_deg: JointLimitsDeg | None = None
    max_joint_speed_rad_s: JointSpeedsRadS | None = None
    _auto_locked: dict = PrivateAttr(default_factory=dict)

    @model_validator(mode="after")
    def _resolve(self, info: ValidationInfo):
        context = info.context or {}
        sources = [k for k in ("model", "urdf", "dh") if getattr(self, k) is not None]
        if len(sources) > 1:
            raise ValueError(f"give one of model, urdf or dh, not {' and '.join(sources)}")
        if not sources:
            object.__setattr__(self, "model", "pa10_7c")
        if self.model is not None and self.model not in MODELS:
            import difflib

            near = difflib.get_close_matches(self.model, MODELS, n=1)
            raise ValueError(f"model {self.model!r} is not a shipped model ({', '.join(MODELS)})"
                             + (f"; did you mean {near[0]!r}?" if near else "; or give urdf = \"file.urdf\""))
        pa10 = self.model == "pa10_7c"
        given = [f for f in PA10_FIELDS if getattr(self, f) is not None]
        if given and not pa10:
            raise ValueError(f"{given[0]} is a PA10-7C field (model = 'pa10_7c'); for this arm edit its "
                             f"{'DH table' if self.dh else 'URDF' if self.urdf else 'model'} instead")
        if self.kernel == "closed_form" and not pa10:
            raise ValueError("kernel = 'closed_form' exists only for the PA10-7C; other arms use 'generic'")
        overrides = [f for f in ("speed_override_rad_s", "range_override_deg") if getattr(self, f)]
        if overrides and pa10 and self.kernel != "generic":
            raise ValueError(f"{overrides[0]} goes with the generic kernel; the PA10's closed form reads "
                             f"joint_limit_deg and max_joint_speed_rad_s (or set kernel = 'generic')")
        if self.urdf is None and (self.base_link or self.tip_link):
            raise ValueError("base_link and tip_link go with urdf")
        if self.dh is None and self.dh_convention is not None:
            raise ValueError("dh_convention goes with dh")
        if self.urdf is not None:
            self._resolve_urdf(context)
        if pa10:
            self._fill_pa10()
        elif self.model is not None:
            m = get_model(self.model)
            self._fill(m.locked_joints_deg, m.seed_deg, m.tool_length_m)
        if self.model is not None and self.spin_joint is None and "spin_joint" not in self.model_fields_set:
            object.__setattr__(self, "spin_joint", get_model(self.model).spin_joint)
        else:
            if self.tool_length_m is None:
                raise ValueError("tool_length_m is required for a URDF or DH arm (the tool tip along the tip "
                                 "link's z axis)")
            if self.dh is not None and self.dh_convention is None:
                object.__setattr__(self, "dh_convention", "standard")
            unlocked = self.locked_joints_deg is None and not context.get("stored")
            self._fill({}, {}, self.tool_length_m)
            if unlocked:
                self._auto_locked = self.redundant_joints()
                object.__setattr__(self, "locked_joints_deg", {n: 0.0 for n in self._auto_locked})
        if not context.get("stored"):
            self.check_chain()
        return self

    def _fill(self, locked, seed, tool_length):
        if self.locked_joints_deg is None:
            object.__setattr__(self, "locked_joints_deg", dict(locked))
        if self.seed_deg is None:
            object.__setattr__(self, "seed_deg", dict(seed))
        if self.tool_length_m is None:
            object.__setattr__(self, "tool_length_m", tool_length)
        if self.tool_axis is None:
            object.__setattr__(self, "tool_axis", [0.0, 0.0, 1.0])
        if self.tool_offset_m is None:
            object.__setattr__(self, "tool_offset_m", [0.0, 0.0, 0.0])
        if math.hypot(*self.tool_axis) < 1e-9:
            raise ValueError("tool_axis must be a direction, not [0, 0, 0]")

    def _fill_pa10(self):
        links = pa10_7c.LINKS_BIELEFELD_M
        for f, v in (("link_d1_m", links[0]), ("link_d3_m", links[1]), ("link_d5_m", links[2]),
                     ("link_d7_m", links[3]), ("tool_length_from", "flange"), ("elbow", "up"),
                     ("joint_limit_deg", JointLimitsDeg()), ("max_joint_speed_rad_s", JointSpeedsRadS())):
            if getattr(self, f) is None:
                object.__setattr__(self, f, v)
        seed = pa10_7c.SEED_DEG if self.elbow == "up" else pa10_7c.SEED_ELBOW_DOWN_DEG
        self._fill(pa10_7c.MODEL.locked_joints_deg, seed, pa10_7c.TOOL_LENGTH_M)

    def _resolve_urdf(self, context):
        from surgopt.files import resolve_and_hash
        from surgopt.robots.chain import MAX_URDF_BYTES

        resolve_and_hash(self, "urdf", "urdf_sha256", MAX_URDF_BYTES, context)

    # ---- the chain ---------------------------------------------------------------------------------------

    @property
    def is_pa10(self) -> bool:
        return self.model == "pa10_7c"

    @property
    def closed_form(self) -> bool:
        """Whether the closed-form PA10 kernel runs (the paper setup's default path)."""
        return self.is_pa10 and self.kernel in ("auto", "closed_form")

    @property
    def tool_past_flange_m(self) -> float | None:
        """How far the tool reaches past the flange (the tip link's origin for other arms): the longest
        insertion below the RCM a tool can take. The one reading of ``tool_length_m``: measured from the flange,
        or for the PA10 with ``tool_length_from = "wrist_centre"`` from the wrist centre, d7 before the flange;
        ``tool()`` and ``tool_offset_pa10_m`` read it from here."""
        if self.tool_length_m is None:
            return None
        if self.is_pa10 and self.tool_length_from == "wrist_centre":
            return self.tool_length_m - self.link_d7_m
        return self.tool_length_m

    @property
    def tool_offset_pa10_m(self) -> float:
        """PA10: wrist centre to tool tip along the tool axis: the given length when it is measured from there,
        else d7 (wrist centre to flange) + ``tool_past_flange_m``."""
        if self.tool_length_from == "wrist_centre":
            return self.tool_length_m
        return self.tool_past_flange_m + self.link_d7_m

    def chain_spec(self):
        """The arm as a ``surgopt.robots.chain.ChainSpec`` (every joint, before locking)."""
        from surgopt.robots import chain

        if self.urdf is not None:  # parsed once per file content and chain ends (validation, tasks, kernels)
            speeds = dict(self.speed_override_rad_s or {})
            return chain.urdf_chain(self.urdf, self.urdf_sha256, self.base_link, self.tip_link,
                                    tuple(sorted(speeds.items())))
        if self.dh is not None:
            return chain.from_dh([r.row(i) for i, r in enumerate(self.dh)], self.dh_convention or "standard")
        if self.is_pa10:
            lim = self.joint_limit_deg.model_dump()
            spd = self.max_joint_speed_rad_s.model_dump()
            rows = pa10_7c.dh_rows((self.link_d1_m, self.link_d3_m, self.link_d5_m, self.link_d7_m), lim, spd)
            return chain.from_dh(rows, "standard")
        m = get_model(self.model)
        return chain.from_dh(m.dh, m.convention)

    def tool(self):
        """Tip link -> tool frame (``surgopt.robots.chain.tool_transform``), ``tool_past_flange_m`` along the
        tool axis."""
        from surgopt.robots.chain import tool_transform

        return tool_transform(self.tool_past_flange_m, self.tool_axis, self.tool_offset_m)

    def chain(self):
        """(kernel ``Chain``, active joint names, seed (rad or m) in their order)."""
        from surgopt.robots.chain import PRISMATIC, reduce_chain

        spec = self.chain_spec()
        kinds = {j.name: j.kind for j in spec.joints}
        locked = {n: (v if kinds.get(n) == PRISMATIC else math.radians(v)) for n, v in self.locked_joints_deg.items()}
        for field, given in (("speed_override_rad_s", self.speed_override_rad_s),
                             ("range_override_deg", self.range_override_deg)):
            unknown = [n for n in (given or {}) if n not in kinds]
            if unknown:
                from surgopt.robots.chain import ChainError

                raise ChainError(field, f"no joint {unknown[0]!r} (joints: {', '.join(kinds)})")
        limits = {n: tuple(v if kinds[n] == PRISMATIC else math.radians(v) for v in lo_hi)
                  for n, lo_hi in (self.range_override_deg or {}).items()}
        chain, names = reduce_chain(spec, locked, self.tool(), speeds=self.speed_override_rad_s, limits=limits)
        unknown = [n for n in self.seed_deg if n not in names]
        if unknown:
            from surgopt.robots.chain import ChainError

            what = "locked" if unknown[0] in locked else "not an active joint"
            raise ChainError("seed_deg", f"{unknown[0]!r} is {what} (active joints: {', '.join(names)})")
        seed = [self.seed_deg.get(n, 0.0) for n in names]
        seed = [v if kinds[n] == PRISMATIC else math.radians(v) for n, v in zip(names, seed)]
        return chain, names, seed

    def spin_speed(self) -> float:
        """The rated speed (rad/s) of ``spin_joint``, after checking that it is locked and that its axis is
        the tool's (a ``ChainError`` otherwise)."""

        from surgopt.robots.chain import ChainError

        spec = self.chain_spec()
        joints = {j.name: j for j in spec.joints}
        if self.spin_joint is None:
            raise ChainError("spin_joint", "metric = 'standard' needs the joint that spins the tool about its own "
                                           "axis (robot.spin_joint)")
        if self.spin_joint not in joints:
            raise ChainError("spin_joint", f"no joint {self.spin_joint!r} (joints: {', '.join(joints)})")
        if self.spin_joint not in self.locked_joints_deg:
            raise ChainError("spin_joint", f"{self.spin_joint!r} must be one of locked_joints_deg (the RCM study's "
                                           f"five active joints do not include it)")
        angle, offset = self.spin_geometry(self.spin_joint)
        if angle > 1e-9 or offset > 1e-9:
            raise ChainError("spin_joint", f"{self.spin_joint!r} does not turn about the tool's axis (an angled "
                                           f"tool mount?): the standard metric's sixth column would be wrong")
        return joints[self.spin_joint].max_speed

    def axis_lines(self) -> tuple[dict, tuple]:
        """At the seed pose (locked joints at their values, the rest at seed_deg or 0), in the base frame: each
        joint's axis line {name: (unit axis, a point on it)} and the tool's line (unit axis, tip)."""
        import numpy as np

        from surgopt.robots.chain import chain_transform, frames_at

        spec = self.chain_spec()
        locked, seed = self.locked_joints_deg or {}, self.seed_deg or {}
        q = [math.radians(locked.get(j.name, seed.get(j.name, 0.0))) for j in spec.joints]
        lines = {}
        for j, f in zip(spec.joints, frames_at(spec, q)):
            axis = f[:3, :3] @ j.axis
            lines[j.name] = (axis / np.linalg.norm(axis), f[:3, 3].copy())
        tool = chain_transform(spec, q) @ self.tool()
        return lines, (tool[:3, 2], tool[:3, 3])

    def spin_geometry(self, joint: str) -> tuple[float, float]:
        """How far ``joint`` is from spinning the tool about its own axis at the seed pose: (the angle between
        its axis and the tool's, rad; the tool tip's distance from its axis, m). Both 0 for a true spin joint."""
        lines, (k, tip) = self.axis_lines()
        return _line_apart(lines[joint], (k, tip))

    def redundant_joints(self) -> dict[str, str]:
        """Joints to lock at 0 when a URDF or DH arm gives no locked_joints_deg and has more than five (#28:
        a UR5/Panda/iiwa-class file runs with the tool length alone): {name: why}. First the last joint, when it
        spins the tool about its own axis (its column of the RCM Jacobian is zero); then, while more than five
        remain, the first joint whose axis line coincides with an earlier free joint's at the zero pose (the
        upper-arm rotation of a 7-axis arm: the shipped Panda's joint3, the iiwa's A3). Revolute joints only."""
        from surgopt.robots.chain import PRISMATIC

        joints = self.chain_spec().joints
        if len(joints) <= 5:
            return {}
        lines, tool = self.axis_lines()
        out: dict[str, str] = {}
        last = joints[-1]
        if last.kind != PRISMATIC and _coincide(_line_apart(lines[last.name], tool)):
            out[last.name] = "it spins the tool about its own axis"
        for i, j in enumerate(joints):
            if len(joints) - len(out) <= 5:
                break
            if j.kind == PRISMATIC or j.name in out:
                continue
            twin = next((e for e in joints[:i] if e.name not in out
                         and _coincide(_line_apart(lines[j.name], lines[e.name]))), None)
            if twin is not None:
                out[j.name] = f"its axis coincides with {twin.name}'s at the zero pose: a redundant rotation"
        return out

    def auto_lock_advice(self) -> list[str]:
        """Says which joints were locked for the user, and why (``redundant_joints``), and which tip link a URDF
        of several leaves was given."""
        tip = [self.chain_spec().note] if self.urdf is not None and self.chain_spec().note else []
        if not self._auto_locked:
            return tip
        return tip + ["robot: no locked_joints_deg: " + "; ".join(f"{n} locked at 0 ({why})"
                                                            for n, why in self._auto_locked.items())
                + " (give robot.locked_joints_deg to choose)"]

    def tool_axis_advice(self) -> list[str]:
        """A word when the arm's last joint is locked but does not turn about the tool's axis (#28 item 3): on
        a wrist whose last joint spins the flange, that means the tool points sideways (a wrong tool_axis, or a
        tip link whose z axis is not the flange's). Empty for the PA10's closed form and for other arms."""
        from surgopt.robots.chain import PRISMATIC

        if self.closed_form or (self.urdf is None and self.dh is None and self.model is None):
            return []
        spec = self.chain_spec()
        last = spec.joints[-1]
        if last.name not in (self.locked_joints_deg or {}) or last.kind == PRISMATIC:
            return []
        angle, offset = self.spin_geometry(last.name)
        if _coincide((angle, offset)):
            return []
        return [f"robot: the last joint {last.name!r} is locked but the tool does not point along its axis (at "
                f"{math.degrees(angle):.0f} deg, the tip {offset * 1000:.0f} mm off it): the tool may stick out "
                f"sideways; check robot.tool_axis (in the tip link's frame) and robot.tip_link"]

    def check_chain(self):
        from surgopt.robots.chain import ChainError

        try:
            spec_ok = False
            self.chain_spec()
            spec_ok = True
            self.chain()
        except ChainError as exc:
            where = f"urdf {self.urdf}: " if self.urdf is not None and not spec_ok else ""
            raise ValueError(f"{where}{exc}") from None


def _line_apart(a: tuple, b: tuple) -> tuple[float, float]:
    """(angle between two lines' directions, rad, either sense; distance of b's point from line a, m)."""
    import numpy as np

    (u, p), (v, q) = a, b
    d = q - p
    angle = float(np.arctan2(np.linalg.norm(np.cross(u, v)), abs(float(u @ v))))
    return angle, float(np.linalg.norm(d - (d @ u) * u))


def _coincide(apart: tuple[float, float]) -> bool:
    """Two lines within 1 deg and 1 mm: one line (a joint spinning the tool, two joints turning about one axis)."""
    return apart[0] <= math.radians(1.0) and apart[1] <= 1e-3


class Workspace(StrictModel):
    """Cube of tool-tip positions centred ``depth_below_rcm_m`` below the RCM."""

    cube_side_m: float = Field(0.05, gt=0, le=1)
    depth_below_rcm_m: float = Field(0.1, gt=0, le=2)
    points_per_side: int = Field(17, ge=1, le=101)


class Grid(StrictModel):
    """A grid of RCM candidates (m). y is one value (0) unless ``y_count`` > 1."""

    x_min_m: float = Field(0.20, ge=-3, le=3)
    x_max_m: float = Field(0.80, ge=-3, le=3)
    x_count: int = Field(121, ge=1, le=2001)
    y_min_m: float = Field(0.0, ge=-3, le=3)
    y_max_m: float = Field(0.0, ge=-3, le=3)
    y_count: int = Field(1, ge=1, le=2001)
    z_min_m: float = Field(-0.60, ge=-3, le=3)
    z_max_m: float = Field(0.00, ge=-3, le=3)
    z_count: int = Field(121, ge=1, le=2001)

    @model_validator(mode="after")
    def _ordered(self):
        for a in "xyz":
            if getattr(self, f"{a}_max_m") < getattr(self, f"{a}_min_m"):
                raise ValueError(f"{a}_max_m must be >= {a}_min_m")
        if self.y_count == 1 and self.y_max_m != self.y_min_m:
            raise ValueError("a y range needs y_count > 1 (or y_min_m == y_max_m for one y)")
        return self


#: The paper's cube (50 mm side, 100 mm below the RCM): its farthest point from the RCM (m). A URDF or DH arm
#: whose tool reaches less than this / WORKSPACE_TOOL_FRACTION past the flange gets the cube scaled down.
PAPER_CUBE_FAR_M = math.sqrt(0.125 ** 2 + 2 * 0.025 ** 2)
WORKSPACE_TOOL_FRACTION = 0.9
#: The grid fields a reach-sized grid fills where the config leaves them out (y too, then: the arm's plane).
REACH_FIELDS = ("x_min_m", "x_max_m", "x_count", "z_min_m", "z_max_m", "z_count")
#: A reach-sized grid has about this many steps across its radius (its spacing rounded to 5 mm).
REACH_GRID_STEPS = 45


def reach_grid(chain) -> dict:
    """``candidates.grid`` fields for an arm's reach (#28 item 5): every point of the tool (flange to tip) lies
    within rho = |p_1 across axis 1| + sum_{k>=2} |p_k| (+ prismatic travel) of the first joint's axis point
    c = o_1 + (p_1 . z_1) z_1, whatever the joint angles, since each joint only turns the links after it about
    its own origin; an RCM lies on the tool, so the disc of radius rho about c in the base's x-z plane through c
    holds every feasible candidate (x >= c_x only when the first axis is vertical: the arm's mirror side adds
    nothing). Spacing rho / REACH_GRID_STEPS rounded to 5 mm: a few thousand candidates, most of them
    unreachable and rejected at their first point."""
    import numpy as np

    z1 = chain.rot[0][:, 2]
    p1 = chain.pos[1]
    c = chain.pos[0] + chain.rot[0] @ np.array([0.0, 0.0, p1[2]])
    travel = np.where(chain.prismatic > 0, np.maximum(np.abs(chain.lower), np.abs(chain.upper)), 0.0)
    if not np.all(np.isfinite(travel)):
        travel = np.where(np.isfinite(travel), travel, 1.0)  # an unlimited slide: a metre (the grid's bound)
    rho = math.hypot(p1[0], p1[1]) + float(np.linalg.norm(chain.pos[2:], axis=1).sum() + travel.sum())
    step = max(0.005, round(rho / REACH_GRID_STEPS / 0.005) * 0.005)
    x0, z0 = (round(float(v) / step) * step for v in (c[0], c[2]))  # on the spacing: round coordinates
    n = math.ceil((rho + step / 2) / step)
    vertical = abs(z1[2]) > 0.999
    x0 = x0 if x0 <= c[0] or not vertical else x0 - step
    x_min = x0 if vertical else x0 - n * step
    return dict(x_min_m=round(max(-3.0, x_min), 4), x_max_m=round(min(3.0, x0 + n * step), 4),
                x_count=n + 1 if vertical else 2 * n + 1, y_min_m=round(float(c[1]), 3),
                y_max_m=round(float(c[1]), 3), y_count=1, z_min_m=round(max(-3.0, z0 - n * step), 4),
                z_max_m=round(min(3.0, z0 + n * step), 4), z_count=2 * n + 1)


class Candidates(StrictModel):
    """RCM candidates: a grid, or an explicit list of [x, z] or [x, y, z] rows (m)."""

    z_reference: Literal["shoulder", "base"] | None = Field(
        None, description="z from the base frame's origin, or (PA10 only) from the shoulder; default: the model's")
    grid: Grid | None = None
    list_m: list[Annotated[list[Finite], Field(min_length=2, max_length=3)]] | None = Field(
        None, min_length=1, max_length=1_000_000, description="[[x, z], ...] or [[x, y, z], ...] in metres")

    @model_validator(mode="after")
    def _one_kind(self):
        if self.grid is not None and self.list_m is not None:
            raise ValueError("give either grid or list_m, not both")
        if self.grid is None and self.list_m is None:
            object.__setattr__(self, "grid", Grid())
        if self.list_m is not None and len({len(r) for r in self.list_m}) > 1:
            raise ValueError("list_m rows must all be [x, z] or all [x, y, z]")
        return self


class RcmSetup(StrictModel):
    """The arm, the workspace and the RCM candidates: what every RCM study shares (rcm-grid, rcm-track)."""

    robot: Robot = Robot()
    workspace: Workspace = Workspace()
    candidates: Candidates = Candidates()
    _grid_from_reach: bool = PrivateAttr(False)

    @model_validator(mode="before")
    @classmethod
    def _model_defaults(cls, data):
        """A shipped model's workspace and candidate grid are the defaults under what the config gives."""
        if not isinstance(data, dict):
            return data
        robot = data.get("robot")
        name = robot.get("model") if isinstance(robot, dict) else None
        if not isinstance(name, str) or name not in MODELS or name == "pa10_7c":
            return data
        m = get_model(name)
        data = dict(data)
        ws = data.get("workspace", {})
        if isinstance(ws, dict):
            data["workspace"] = {**m.workspace, **ws}
        cand = data.get("candidates", {})
        if isinstance(cand, dict) and "list_m" not in cand:
            grid = cand.get("grid", {})
            if isinstance(grid, dict):
                data["candidates"] = {**cand, "grid": {**m.grid, **grid}}
        return data

    @model_validator(mode="after")
    def _z_reference(self):
        if self.candidates.z_reference is None:  # a copy: the default Candidates() instance is shared
            object.__setattr__(self, "candidates", self.candidates.model_copy(
                update={"z_reference": "shoulder" if self.robot.is_pa10 else "base"}))
        if self.candidates.z_reference == "shoulder" and not self.robot.is_pa10:
            raise ValueError("candidates.z_reference = 'shoulder' is the PA10's; other arms use 'base'")
        return self

    @model_validator(mode="after")
    def _sized_to_the_arm(self):
        """A URDF or DH arm's candidate grid, where the config leaves it out, covers every RCM its tool can hold
        (#28 item 5; ``reach_grid``), and the paper's workspace cube shrinks to fit a tool too short for it."""
        r = self.robot
        if r.urdf is None and r.dh is None:
            return self
        ws = self.workspace
        if not ws.model_fields_set and r.tool_length_m < PAPER_CUBE_FAR_M / WORKSPACE_TOOL_FRACTION:
            k = r.tool_length_m * WORKSPACE_TOOL_FRACTION / PAPER_CUBE_FAR_M
            object.__setattr__(self, "workspace", ws.model_copy(update={
                "cube_side_m": round(ws.cube_side_m * k, 4), "depth_below_rcm_m": round(ws.depth_below_rcm_m * k, 4)}))
        grid = self.candidates.grid
        if grid is not None and set(REACH_FIELDS) - grid.model_fields_set:
            fitted = reach_grid(*r.chain()[:1])
            given = {f: getattr(grid, f) for f in grid.model_fields_set}
            object.__setattr__(self, "candidates", self.candidates.model_copy(
                update={"grid": Grid(**{**fitted, **given})}))
            self._grid_from_reach = True
        return self

    @property
    def grid_from_reach(self) -> bool:
        """Whether the candidate grid (some of its fields) was sized from the arm's reach at validation."""
        return self._grid_from_reach

    @model_validator(mode="after")
    def _workspace_on_the_tool(self):
        """The RCM geometry every pose must satisfy (docs/robots.md): the tip is below the RCM, inside the body
        (insertion > 0), and the RCM lies on the tool, between the flange and the tip (insertion <= the tool's
        length past the flange), so the arm stays outside. The workspace is placed relative to the RCM, so this
        holds for every candidate or for none: checked before anything runs."""
        ws = self.workspace
        half = ws.cube_side_m / 2 if ws.points_per_side > 1 else 0.0  # one point per side: the centre alone
        near = ws.depth_below_rcm_m - half
        if near <= 0:
            raise ValueError(f"workspace: the cube reaches {-near * 1000:.0f} mm above the RCM; every tool tip must "
                             f"be below it, inside the body (depth_below_rcm_m > cube_side_m / 2)")
        far = math.sqrt((ws.depth_below_rcm_m + half) ** 2 + 2 * half ** 2)
        tool = self.robot.tool_past_flange_m
        if tool is not None and far > tool:
            raise ValueError(f"workspace: its farthest point is {far * 1000:.0f} mm from the RCM but the tool reaches "
                             f"{tool * 1000:.0f} mm past the flange, so the RCM would lie on the arm, not on the tool: "
                             f"no candidate can be a real set-up (a tool of at least {far:.3f} m past the flange, or "
                             f"a workspace closer to the RCM)")
        return self


class StandardTaskScale(StrictModel):
    """Task scaling of the standard Jacobian (Locke & Patel Sec. III-E: 10 mm/s and pi/2 rad/s)."""

    linear_m_per_s: float = Field(0.01, gt=0, le=100)
    angular_rad_per_s: float = Field(math.pi / 2, gt=0, le=1000)


class RcmGridConfig(RcmSetup):
    search: search_field("full", "cull") = Field(
        "full", description="'full' map, 'cull' (exact argmax), or a [search] table (an optimiser over x, z)")
    metric: Literal[tuple(POSE_METRICS)] = Field(
        "alternative", description="the GII of the alternative Jacobian under the RCM constraint (eq. 8), or of "
                                   "the standard Jacobian at the same poses (Sec. III-E; the generic kernel)")
    standard_task_scale: StandardTaskScale = StandardTaskScale()

    @model_validator(mode="after")
    def _consistent(self):
        if self.metric == "standard":
            if self.search == "cull":
                raise ValueError("--cull bounds the RCM metric; with metric = 'standard' run the full map")
            if self.robot.kernel == "closed_form":
                raise ValueError("metric = 'standard' runs on the generic kernel: robot.kernel = 'auto' or 'generic'")
            from surgopt.robots.chain import ChainError

            try:
                self.robot.spin_speed()
            except ChainError as exc:
                raise ValueError(f"robot.{exc}") from None
        if isinstance(self.search, SearchSpec) and self.candidates.list_m is not None:
            raise ValueError("a [search] optimises over candidates.grid's ranges: give a grid, not list_m")
        check_objectives(self.search, search_objectives(self.metric))
        return self

    def metric_params(self) -> tuple[float, ...]:
        """The per-pose metric's kernel parameters (``metrics.POSE_METRICS``): the standard metric's task
        scaling (m/s, rad/s) and the tool-spin joint's rated speed; none for the RCM metric."""
        if self.metric == "standard":
            ts = self.standard_task_scale
            return ts.linear_m_per_s, ts.angular_rad_per_s, self.robot.spin_speed()
        return ()
