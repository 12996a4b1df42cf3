"""An RCM arm read from a DH table or a URDF file, checked to be a yaw / pitch / insertion mechanism and reduced to
what the port-placement study's closed form needs (issue #29: "any RCM arm from a DH table / URDF").

The closed form (``surgopt.kinematics.port_place``) puts the reaching point (an instrument's wrist, a scope's
tip) at p = (q3 + c) u(q1, q2), u = (sin q1 cos q2, -sin q2, -cos q1 cos q2), in a base frame at the RCM: yaw q1
turns the shaft about the base's -y axis, pitch q2 about the turned -x axis, insertion q3 slides the shaft along
-z at q = 0. An arm described as a serial chain is that mechanism when, at its zero pose,

- its first two joints are revolute and their axis lines meet (the meeting point is the RCM),
- its third joint is prismatic and slides along a line through the RCM (the shaft),
- yaw axis, pitch axis and shaft are mutually orthogonal,
- the reaching point lies on the shaft: where the first later joint axis that is not along the shaft (the
  wrist's first axis; a roll about the shaft is passed over) crosses it, or the tip link's origin.

Then the arm's base frame B has z = -shaft, y = -yaw axis, x = y x z, and the arm's joints map to the closed
form's as q1 = q1_arm, q2 = s q2_arm (s = +1 when the pitch axis is -x, -1 when +x), q3 = q3_arm, c the
reaching point's signed distance from the RCM along the shaft at q3 = 0. ``rcm_mechanism`` checks every
condition (each failure names what is wrong, in mm or degrees) and then holds the closed form to the chain's
own forward kinematics at 64 joint values spread over the limits, to 1e-9 m.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from surgopt.robots.chain import PRISMATIC, REVOLUTE, ChainError, ChainSpec, axis_motion

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


def _frames_at_zero(spec: ChainSpec) -> list[np.ndarray]:
    """Each joint's frame (before its own motion) in the base frame at q = 0."""
    out, t = [], np.eye(4)
    for j in spec.joints:
        t = t @ j.origin
        out.append(t.copy())
    return out


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


def rcm_mechanism(spec: ChainSpec, name: str, source: str, where: str) -> RcmLimits:
    """The closed form's ranges and offsets of a chain that is a yaw / pitch / insertion RCM mechanism, or a
    ``ChainError`` at ``where`` (the config field) saying which condition fails and by how much."""
    joints = spec.joints
    if len(joints) < 3:
        raise ChainError(where, f"{len(joints)} joint(s); an RCM arm needs yaw, pitch and insertion")
    kinds = [j.kind for j in joints[:3]]
    if kinds[0] == PRISMATIC or kinds[1] == PRISMATIC or kinds[2] != PRISMATIC:
        raise ChainError(where, f"its first three joints are {', '.join(kinds)}; the closed form needs revolute "
                                f"(yaw), revolute (pitch), prismatic (insertion): other mechanisms would need "
                                f"the generic serial solver, which port-place does not run")
    frames = _frames_at_zero(spec)
    axes = [f[:3, :3] @ j.axis for f, j in zip(frames, joints)]
    points = [f[:3, 3] for f in frames]
    _, _, gap = closest_points(points[0], axes[0], points[1], axes[1])
    x, y, _ = closest_points(points[0], axes[0], points[1], axes[1])
    if gap > MEET_M:
        raise ChainError(where, f"the yaw and pitch axes ({joints[0].name}, {joints[1].name}) do not meet: "
                                f"{gap * 1000:.3f} mm apart at the zero pose, so there is no remote centre of motion")
    rcm = (x + y) / 2
    shaft = axes[2]
    off = np.linalg.norm(np.cross(rcm - points[2], shaft))
    if off > MEET_M:
        raise ChainError(where, f"the insertion ({joints[2].name}) slides along a line {off * 1000:.3f} mm from the "
                                f"RCM: the shaft does not pass through it")
    for (a, b), what in (((0, 1), "yaw and pitch axes"), ((1, 2), "pitch axis and shaft"),
                         ((0, 2), "yaw axis and shaft")):
        c = abs(float(axes[a] @ axes[b]))
        if c > ORTHOGONAL_COS:
            raise ChainError(where, f"the {what} are at {math.degrees(math.acos(min(1.0, c))):.3f} deg, not 90: the "
                                    f"closed form needs them orthogonal at the zero pose (other RCM geometries "
                                    f"would need the generic serial solver, which port-place does not run)")
    reach, wrist = _reaching_point(spec, frames, axes, points, rcm, shaft, where)
    along = float((reach - rcm) @ shaft)
    z = -shaft
    yb = -axes[0]
    xb = np.cross(yb, z)
    sign = -float(np.sign(axes[1] @ xb))  # +1 when the pitch axis is -x
    base = np.column_stack([xb, yb, z])
    yaw = _limits(joints[0], where)
    pitch = tuple(sorted(sign * v for v in _limits(joints[1], where)))
    insertion = _limits(joints[2], where)
    arm = RcmLimits(name, source, yaw, pitch, insertion, along, wrist)
    _hold_to_fk(spec, arm, base, rcm, reach, sign, where)
    return arm


def _reaching_point(spec, frames, axes, points, rcm, shaft, where):
    """(the reaching point at q = 0, the wrist's bend): where the first joint axis after the insertion that is
    not along the shaft crosses it (the wrist's first axis), else the tip link's origin; the bend is the least
    half-range of the first two wrist joints (0 with fewer than two)."""
    later = [k for k in range(3, len(spec.joints)) if spec.joints[k].kind != PRISMATIC
             and np.linalg.norm(np.cross(axes[k], shaft)) > ORTHOGONAL_COS]
    if later:
        k = later[0]
        x, y, gap = closest_points(rcm, shaft, points[k], axes[k])
        if gap > MEET_M:
            raise ChainError(where, f"the wrist's first axis ({spec.joints[k].name}) passes {gap * 1000:.3f} mm from "
                                    f"the shaft: the reaching point is not on it")
        reach = x
    else:
        tip = (frames[-1] @ axis_motion(spec.joints[-1].axis, spec.joints[-1].kind, 0.0) @ spec.tail)[:3, 3]
        off = np.linalg.norm(np.cross(tip - rcm, shaft))
        if off > MEET_M:
            raise ChainError(where, f"the tip link's origin is {off * 1000:.3f} mm off the shaft: the reaching point "
                                    f"is not on it")
        reach = tip
    wrist = [spec.joints[k] for k in later[:2] if spec.joints[k].kind == REVOLUTE]
    bend = min(min(-j.lower, j.upper) for j in wrist) if len(wrist) == 2 else 0.0
    return reach, max(0.0, bend)


def _hold_to_fk(spec, arm, base, rcm, reach, sign, where) -> None:
    """The closed form p = rcm + base (q3 + c) u(q1, s q2) against the chain's forward kinematics of the reaching
    point (carried by the insertion's frame) at 64 joint values spread over the limits."""
    third = np.eye(4)
    for j in spec.joints[:3]:
        third = third @ j.origin
    local = np.linalg.solve(third, np.append(reach, 1.0))  # the point in the insertion's frame at q = 0
    rng = np.random.default_rng(0)
    lo = np.array([arm.yaw_limits_rad[0], spec.joints[1].lower, arm.insertion_limits_m[0]])
    hi = np.array([arm.yaw_limits_rad[1], spec.joints[1].upper, arm.insertion_limits_m[1]])
    lo[1], hi[1] = max(lo[1], -math.pi), min(hi[1], math.pi)
    for q in lo + rng.random((64, 3)) * (hi - lo):
        t = np.eye(4)
        for j, v in zip(spec.joints[:3], q):
            t = t @ j.origin @ axis_motion(j.axis, j.kind, v)
        fk = (t @ local)[:3]
        q1, q2, q3 = q[0], sign * q[1], q[2]
        u = np.array([math.sin(q1) * math.cos(q2), -math.sin(q2), -math.cos(q1) * math.cos(q2)])
        closed = rcm + base @ ((q3 + arm.along_shaft_m) * u)
        miss = float(np.linalg.norm(fk - closed))
        if miss > FK_TOLERANCE_M:
            raise ChainError(where, f"not a yaw / pitch / insertion RCM mechanism: at q = ({q[0]:.3f}, {q[1]:.3f}, "
                                    f"{q[2]:.4f}) the reaching point is {miss * 1000:.4f} mm from the closed form")
