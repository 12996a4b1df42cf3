"""An RCM arm read from a DH table or a URDF file, checked to be a yaw / pitch / insertion mechanism about a remote
centre of motion and reduced to what the port-placement study's closed forms need (issue #29: "any RCM arm from
a DH table / URDF").

The closed forms (``surgopt.kinematics.port.place``) put the reaching point (an instrument's wrist, a scope's
tip) at p = (q3 + c) u(q1, q2), u = R(w1, q1) R(w2, q2) s, in a base frame B at the RCM with the shaft s = -z at
q = 0: yaw q1 turns the shaft about the fixed axis w1, pitch q2 about the axis w2 that the yaw carries, and
insertion q3 slides it. An arm described as a serial chain is that mechanism when, at its neutral pose (yaw and
pitch 0, or the middle of a range that excludes 0: the pose it is docked in, shaft toward the target's centre),

- its first two joints are revolute and their axis lines meet (the meeting point is the RCM),
- then, after any rolls about the shaft (the Raven's tool roll), a prismatic joint slides along a line
  through the RCM (the shaft),
- no two of yaw axis, pitch axis and shaft are parallel,
- the reaching point lies on the shaft: where the first later joint axis that is not along the shaft (the
  wrist's first axis; a roll about the shaft is passed over) crosses it, or the tip link's origin.

B has z = -shaft, y = -(the yaw axis made orthogonal to the shaft), x = y x z. When the three directions are
mutually orthogonal (the dVRK's arms) w1 = -y and w2 = +-x and the arm is the orthogonal closed form
(u = (sin q1 cos q2, -sin q2, -cos q1 cos q2)) with q2 = s q2_arm (s = +1 when the pitch axis is -x); otherwise
(a spherical mechanism such as the Raven's, links at 75 and 52 deg) it keeps its axes and the kernels solve it
by Paden-Kahan's subproblem 2. Angles are taken from the neutral pose. c is the reaching point's signed
distance from the RCM along the shaft at q3 = 0. ``rcm_mechanism`` checks every condition (each failure names what is wrong, in mm or degrees) and then
holds the closed form to the chain's own forward kinematics at 64 joint values spread over the limits, to
1e-9 m.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from surgopt.robots.chain import PRISMATIC, REVOLUTE, ChainError, ChainSpec, axis_motion, chain_transform, frames_at
from surgopt.robots.dvrk import OUTSIDE_LENGTH_M

#: Lines meet, a point lies on a line: within this distance (m); axes are orthogonal within this cosine.
MEET_M = 1e-6
ORTHOGONAL_COS = 1e-6
#: The closed form against the chain's forward kinematics (m).
FK_TOLERANCE_M = 1e-9


@dataclass(frozen=True)
class RcmLimits:
    """What the port-placement study reads of an RCM arm (the same names as ``dvrk.RcmArm``'s): the closed form's
    yaw, pitch and insertion ranges, the reaching point's shaft offset, and how far the wrist can turn the
    jaws off the shaft (0 without a wrist)."""

    name: str
    source: str
    yaw_limits_rad: tuple[float, float]
    pitch_limits_rad: tuple[float, float]
    insertion_limits_m: tuple[float, float]
    along_shaft_m: float
    wrist_bend_rad: float
    #: a spherical mechanism's yaw axis and pitch axis (at q1 = 0) in B; None: the orthogonal closed form
    yaw_axis: tuple[float, float, float] | None = None
    pitch_axis: tuple[float, float, float] | None = None
    #: the arm's own yaw and pitch at the neutral pose (the closed form's 0): 0, or a range's middle
    neutral_rad: tuple[float, float] = (0.0, 0.0)
    #: where the file puts the RCM (m) and the closed form's base frame B (its columns x, y, z), in the file's
    #: base frame
    rcm_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
    base_rotation: tuple[tuple[float, float, float], ...] = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
    #: the outside segment of the instruments' external clearance (m): an arm from a file gives none, so the
    #: Classic PSM's (``dvrk.OUTSIDE_LENGTH_M``, an assumption), as the clearance has always taken it
    outside_length_m: float = OUTSIDE_LENGTH_M


def closest_points(p, a, q, b):
    """The closest points of lines p + s a and q + t b (unit a, b), and their distance (parallel lines: p's
    foot on the other line)."""
    w = p - q
    c = float(a @ b)
    denom = 1.0 - c * c
    if denom < 1e-15:
        s, t = 0.0, float(w @ b)
    else:
        s = (c * float(w @ b) - float(w @ a)) / denom
        t = (float(w @ b) - c * float(w @ a)) / denom
    x, y = p + s * a, q + t * b
    return x, y, float(np.linalg.norm(x - y))


def _limits(joint, where: str) -> tuple[float, float]:
    lo, hi = joint.lower, joint.upper
    if not (math.isfinite(lo) and math.isfinite(hi)):
        lo, hi = max(lo, -math.pi), min(hi, math.pi)  # a continuous joint: one turn
    if not lo < hi:
        raise ChainError(where, f"joint {joint.name!r} cannot move (limits [{lo:g}, {hi:g}])")
    return lo, hi


def neutral(lo: float, hi: float) -> float:
    """A joint's neutral value: 0 when its range holds it, else the middle of the range."""
    return 0.0 if lo <= 0.0 <= hi else 0.5 * (lo + hi)


def rcm_mechanism(spec: ChainSpec, name: str, source: str, where: str) -> RcmLimits:
    """The closed form's ranges and offsets of a chain that is a yaw / pitch / insertion RCM mechanism, or a
    ``ChainError`` at ``where`` (the config field) saying which condition fails and by how much. The mechanism is
    read at its neutral pose (yaw and pitch 0, or the middle of a range that excludes 0): the pose in which it is
    docked with the shaft toward the target's centre; the closed form's angles are taken from there."""
    joints = spec.joints
    kinds = [j.kind for j in joints]
    insertion = next((k for k in range(2, len(joints)) if kinds[k] == PRISMATIC), None)
    if len(joints) < 3 or PRISMATIC in kinds[:2] or insertion is None:
        raise ChainError(where, f"its joints are {', '.join(kinds) or 'none'}; an RCM arm needs revolute (yaw), "
                                f"revolute (pitch), any rolls about the shaft, then prismatic (insertion): other "
                                f"mechanisms would need the generic serial solver, which port-place does not run")
    yaw, pitch = _limits(joints[0], where), _limits(joints[1], where)
    home = (neutral(*yaw), neutral(*pitch))
    frames = frames_at(spec, home)
    axes = [f[:3, :3] @ j.axis for f, j in zip(frames, joints)]
    points = [f[:3, 3] for f in frames]
    x, y, gap = closest_points(points[0], axes[0], points[1], axes[1])
    if gap > MEET_M:
        raise ChainError(where, f"the yaw and pitch axes ({joints[0].name}, {joints[1].name}) do not meet: "
                                f"{gap * 1000:.3f} mm apart, so there is no remote centre of motion")
    rcm = (x + y) / 2
    shaft = axes[insertion]
    for k in range(2, insertion + 1):  # the rolls before the insertion and the insertion: on the shaft's line
        off = np.linalg.norm(np.cross(rcm - points[k], shaft))
        parallel = np.linalg.norm(np.cross(axes[k], shaft))
        if off > MEET_M or parallel > ORTHOGONAL_COS:
            what = "the insertion slides" if k == insertion else "a joint between pitch and insertion turns"
            raise ChainError(where, f"{what} ({joints[k].name}) along a line {off * 1000:.3f} mm from the RCM and "
                                    f"{math.degrees(math.asin(min(1.0, parallel))):.3f} deg off the shaft: the "
                                    f"shaft does not pass through the RCM")
    cosines = {}
    for (a, b), what in (((0, 1), "yaw and pitch axes"), ((1, insertion), "pitch axis and shaft"),
                         ((0, insertion), "yaw axis and shaft")):
        cosines[what] = c = abs(float(axes[a] @ axes[b]))
        if c > 1.0 - 1e-9:
            raise ChainError(where, f"the {what} are parallel: the two revolute joints cannot point the shaft")
    reach, wrist = _reaching_point(spec, home, axes, points, rcm, shaft, insertion, where)
    along = float((reach - rcm) @ shaft)
    z = -shaft
    yb = -(axes[0] - (axes[0] @ shaft) * shaft)
    yb = yb / np.linalg.norm(yb)
    xb = np.cross(yb, z)
    base = np.column_stack([xb, yb, z])
    yaw = (yaw[0] - home[0], yaw[1] - home[0])
    pitch = (pitch[0] - home[1], pitch[1] - home[1])
    depth = _limits(joints[insertion], where)
    if max(cosines.values()) <= ORTHOGONAL_COS:  # the orthogonal closed form
        sign = -float(np.sign(axes[1] @ xb))  # +1 when the pitch axis is -x
        arm = RcmLimits(name, source, yaw, tuple(sorted(sign * v for v in pitch)), depth, along, wrist)
    else:  # a spherical mechanism: its own axes, in B
        sign = 1.0
        arm = RcmLimits(name, source, yaw, pitch, depth, along, wrist,
                        tuple(float(v) for v in base.T @ axes[0]), tuple(float(v) for v in base.T @ axes[1]))
    arm = replace(arm, neutral_rad=home, rcm_m=tuple(float(v) for v in rcm),
                  base_rotation=tuple(tuple(float(v) for v in row) for row in base))
    _hold_to_fk(spec, arm, base, rcm, reach, sign, insertion, where)
    return arm


def _reaching_point(spec, home, axes, points, rcm, shaft, insertion, where):
    """(the reaching point at q = 0, the wrist's bend): where the first joint axis after the insertion that is
    not along the shaft crosses it (the wrist's first axis), else the tip link's origin; the bend is the least
    half-range of the first two wrist joints (0 with fewer than two)."""
    later = [k for k in range(insertion + 1, len(spec.joints)) if spec.joints[k].kind != PRISMATIC
             and np.linalg.norm(np.cross(axes[k], shaft)) > ORTHOGONAL_COS]
    if later:
        k = later[0]
        x, y, gap = closest_points(rcm, shaft, points[k], axes[k])
        if gap > MEET_M:
            raise ChainError(where, f"the wrist's first axis ({spec.joints[k].name}) passes {gap * 1000:.3f} mm from "
                                    f"the shaft: the reaching point is not on it")
        reach = x
    else:
        tip = chain_transform(spec, list(home) + [0.0] * (len(spec.joints) - 2))[:3, 3]
        off = np.linalg.norm(np.cross(tip - rcm, shaft))
        if off > MEET_M:
            raise ChainError(where, f"the tip link's origin is {off * 1000:.3f} mm off the shaft: the reaching point "
                                    f"is not on it")
        reach = tip
    wrist = [spec.joints[k] for k in later[:2] if spec.joints[k].kind == REVOLUTE]
    bend = min(min(-j.lower, j.upper) for j in wrist) if len(wrist) == 2 else 0.0
    return reach, max(0.0, bend)


def _hold_to_fk(spec, arm, base, rcm, reach, sign, insertion, where) -> None:
    """The closed form p = rcm + base (q3 + c) u(q1, s q2) (a spherical arm: u = R(w1, q1) R(w2, q2) (0, 0, -1)),
    its angles from the neutral pose, against the chain's forward kinematics of the reaching point (carried by
    the insertion's frame; rolls at 0) at 64 joint values spread over the limits."""
    home = arm.neutral_rad
    local = np.linalg.solve(frames_at(spec, home)[insertion], np.append(reach, 1.0))  # in the insertion's frame
    rng = np.random.default_rng(0)
    lo = np.array([arm.yaw_limits_rad[0], spec.joints[1].lower - home[1], arm.insertion_limits_m[0]])
    hi = np.array([arm.yaw_limits_rad[1], spec.joints[1].upper - home[1], arm.insertion_limits_m[1]])
    lo[1], hi[1] = max(lo[1], -math.pi), min(hi[1], math.pi)
    for q in lo + rng.random((64, 3)) * (hi - lo):
        values = [0.0] * (insertion + 1)
        values[0], values[1], values[insertion] = q[0] + home[0], q[1] + home[1], q[2]
        slide = axis_motion(spec.joints[insertion].axis, PRISMATIC, q[2])
        fk = (frames_at(spec, values)[insertion] @ slide @ local)[:3]
        q1, q2, q3 = q[0], sign * q[1], q[2]
        if arm.yaw_axis is None:
            u = np.array([math.sin(q1) * math.cos(q2), -math.sin(q2), -math.cos(q1) * math.cos(q2)])
        else:
            u = (axis_motion(arm.yaw_axis, REVOLUTE, q1)[:3, :3] @ axis_motion(arm.pitch_axis, REVOLUTE, q2)[:3, :3]
                 @ np.array([0.0, 0.0, -1.0]))
        closed = rcm + base @ ((q3 + arm.along_shaft_m) * u)
        miss = float(np.linalg.norm(fk - closed))
        if miss > FK_TOLERANCE_M:
            raise ChainError(where, f"not a yaw / pitch / insertion RCM mechanism: at q = ({values[0]:.3f}, "
                                    f"{values[1]:.3f}, {q[2]:.4f}) the reaching point is {miss * 1000:.4f} mm from "
                                    f"the closed form")
