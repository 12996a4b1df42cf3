"""Serial arms as data: DH tables (standard or modified) and URDF chains in one form, reduced for the kernel.

One form (``ChainSpec``): per joint a fixed origin transform (from the previous joint's moved frame to
this joint's frame), a unit axis in that frame, revolute / continuous / prismatic, limits and rated
speed; then a fixed ``tail`` to the tip link. ``reduce_chain`` folds the locked joints into the fixed
transforms, rotates each active joint's frame so that its axis is z, and appends the tool, giving the
kernel's ``serial_chain.Chain``. Pure numpy; the URDF is parsed by ``yourdfpy`` (no meshes loaded). One
module (~450 lines): the DH and URDF readers produce the one form the reduction reads.

Errors are ``ChainError`` with the element (URDF joint or link, DH row, joint name) named; the config
layer turns them into config errors on the field that brought the robot in.
"""
from __future__ import annotations

from functools import lru_cache

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

import numpy as np

REVOLUTE, CONTINUOUS, PRISMATIC = "revolute", "continuous", "prismatic"


class Chain(NamedTuple):
    """A serial chain reduced to five active joints, each moving about or along its local z axis.

    ``rot`` (6, 3, 3), ``pos`` (6, 3): the fixed transforms P_0..P_5 (P_5 ends at the tool tip, its z
    the tool axis); ``prismatic`` (5,) 1.0 for a sliding joint; ``lower``/``upper`` (5,) joint limits
    (rad or m, +-inf when unlimited); ``qdot_max`` (5,) rated speeds (rad/s or m/s), the diagonal of Q.
    """

    rot: np.ndarray
    pos: np.ndarray
    prismatic: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    qdot_max: np.ndarray


class ChainError(ValueError):
    """A robot description that cannot be a serial chain for the RCM study; ``where`` names the element."""

    def __init__(self, where: str, message: str):
        super().__init__(f"{where}: {message}")
        self.where = where


@dataclass(frozen=True)
class Joint:
    name: str
    origin: np.ndarray  # (4, 4): previous moved frame -> this joint's frame
    axis: np.ndarray  # (3,) unit, in this joint's frame
    kind: str  # REVOLUTE | CONTINUOUS | PRISMATIC
    lower: float  # rad or m; -inf when unlimited
    upper: float
    max_speed: float  # rad/s or m/s


@dataclass(frozen=True)
class ChainSpec:
    joints: tuple[Joint, ...]
    tail: np.ndarray = field(default_factory=lambda: np.eye(4))  # last joint's moved frame -> tip link
    note: str = ""  # a choice made for the user (a URDF's tip link among several leaves), said with the run

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(j.name for j in self.joints)


def rot_x(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    t = np.eye(4)
    t[1:3, 1:3] = [[c, -s], [s, c]]
    return t


def rot_y(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    t = np.eye(4)
    t[0, 0], t[0, 2], t[2, 0], t[2, 2] = c, s, -s, c
    return t


def rot_z(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    t = np.eye(4)
    t[0:2, 0:2] = [[c, -s], [s, c]]
    return t


def trans(x: float, y: float, z: float) -> np.ndarray:
    t = np.eye(4)
    t[:3, 3] = (x, y, z)
    return t


def axis_motion(axis, kind: str, q: float) -> np.ndarray:
    """The joint's motion: a turn by q about ``axis`` (Rodrigues) or a slide by q along it."""
    a = np.asarray(axis, float)
    t = np.eye(4)
    if kind == PRISMATIC:
        t[:3, 3] = q * a
        return t
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    t[:3, :3] = np.eye(3) + math.sin(q) * k + (1 - math.cos(q)) * (k @ k)
    return t


@dataclass(frozen=True)
class DhRow:
    """One DH row, of either convention (``from_dh`` is told which): a (m), alpha (rad), d (m), theta offset
    (rad), limits, rated speed, optional name; the one DH row type (shipped models, config tables, the dVRK).

    Revolute rows: ``lower``/``upper`` in rad (None: continuous), ``max_speed`` in rad/s. A prismatic row slides
    along d (``d`` is then its offset), limits in m, speed in m/s. ``DhRow.deg`` builds a row from degrees (a
    data sheet's), converting each angle once with ``math.radians``.
    """

    a_m: float
    alpha_rad: float
    d_m: float
    theta_offset_rad: float = 0.0
    lower: float | None = None
    upper: float | None = None
    max_speed: float = 1.0
    name: str | None = None
    prismatic: bool = False

    @classmethod
    def deg(cls, a_m: float, alpha_deg: float, d_m: float, theta_offset_deg: float = 0.0,
            lower: float | None = None, upper: float | None = None, max_speed: float = 1.0, name: str | None = None,
            prismatic: bool = False) -> "DhRow":
        """A row from angles in degrees (a revolute row's limits too; a prismatic row's stay in m)."""
        limit = (lambda v: v) if prismatic else (lambda v: None if v is None else math.radians(v))
        return cls(a_m, math.radians(alpha_deg), d_m, math.radians(theta_offset_deg), limit(lower), limit(upper),
                   max_speed, name, prismatic)


def from_dh(rows, convention: str = "standard") -> ChainSpec:
    """A ``ChainSpec`` from DH rows.

    standard (distal): T_i = Rz(theta_i) Tz(d_i) Tx(a_i) Rx(alpha_i);
    modified (proximal, Craig): T_i = Rx(alpha_i) Tx(a_i) Rz(theta_i) Tz(d_i), each row holding its
    own (a_{i-1}, alpha_{i-1}) as Robotics Toolbox's ``RevoluteMDH`` does. The joint moves theta (or d).
    """
    if convention not in ("standard", "modified"):
        raise ChainError("dh_convention", f"{convention!r} is not 'standard' or 'modified'")
    joints = []
    before = np.eye(4)
    for i, r in enumerate(rows):
        name = r.name or f"j{i + 1}"
        off = r.theta_offset_rad
        if r.prismatic:
            lo, hi = (-math.inf if r.lower is None else r.lower), (math.inf if r.upper is None else r.upper)
            kind, fixed_after = PRISMATIC, rot_z(off) @ trans(0, 0, r.d_m)
        else:
            lo = -math.inf if r.lower is None else r.lower
            hi = math.inf if r.upper is None else r.upper
            kind, fixed_after = (CONTINUOUS if r.lower is None and r.upper is None else REVOLUTE), \
                rot_z(off) @ trans(0, 0, r.d_m)
        if convention == "standard":
            origin, after = before, fixed_after @ trans(r.a_m, 0, 0) @ rot_x(r.alpha_rad)
        else:
            origin, after = before @ rot_x(r.alpha_rad) @ trans(r.a_m, 0, 0), fixed_after
        joints.append(Joint(name, origin, np.array([0.0, 0.0, 1.0]), kind, lo, hi, float(r.max_speed)))
        before = after
    return ChainSpec(tuple(joints), before)


#: The tip link a URDF's chain ends at when it has several leaves and none is named (ROS-Industrial's convention:
#: example-robot-data's ur5_robot.urdf has base, ee_link and tool0).
TOOL_FRAME = "tool0"


@lru_cache(maxsize=16)
def urdf_chain(path: str, sha256: str | None, base_link: str, tip_link: str, speeds: tuple = ()) -> "ChainSpec":
    """``from_urdf`` of one file content (``sha256``, the config's hash of it) between two links, with
    ``speeds`` ((joint, rad/s) pairs), parsed once per process: a ChainSpec is never modified."""
    return from_urdf(path, base_link, tip_link, dict(speeds))


def from_urdf(path: str | Path, base_link: str | None, tip_link: str | None,
              speeds: dict[str, float] | None = None) -> ChainSpec:
    """The chain from ``base_link`` to ``tip_link`` of a URDF file (yourdfpy; no meshes loaded).

    Defaults: the URDF's root link, and its only leaf (of several, ``TOOL_FRAME``, said in ``note``). Fixed joints
    fold into the next origin;
    continuous joints have no limits; floating and planar joints, mimic joints and missing or
    unknown links are ``ChainError``s naming the element.
    """
    import logging

    import yourdfpy

    check_urdf_numbers(parse_urdf_strictly(path))
    log = logging.getLogger("yourdfpy")
    level = log.level
    log.setLevel(logging.CRITICAL)  # its parse errors are ours to report, in one line
    try:
        urdf = yourdfpy.URDF.load(str(path), load_meshes=False, build_scene_graph=False,
                                  load_collision_meshes=False)
    except Exception as exc:  # noqa: BLE001 - lxml, ValueError, KeyError: a file that is not a URDF
        raise ChainError(str(path), f"not a readable URDF: {_first_line(exc)}") from None
    finally:
        log.setLevel(level)
    robot = urdf.robot
    links = {link.name for link in robot.links}
    by_child = {}
    for j in robot.joints:
        if j.child in by_child:
            raise ChainError(f"joint {j.name!r}", f"link {j.child!r} is already the child of joint "
                                                  f"{by_child[j.child].name!r}: a link has one parent in a tree "
                                                  f"(a kinematic loop or a duplicated joint)")
        if j.child not in links:
            raise ChainError(f"joint {j.name!r}", f"child link {j.child!r} is not a <link> of the URDF")
        if j.parent not in links:
            raise ChainError(f"joint {j.name!r}", f"parent link {j.parent!r} is not a <link> of the URDF")
        by_child[j.child] = j
    children = {j.parent for j in robot.joints}
    roots = sorted(links - set(by_child))
    leaves = sorted(links - children)
    if base_link is None:
        if len(roots) != 1:
            raise ChainError("base_link", f"the URDF has {len(roots)} root links ({', '.join(roots)}); name one")
        base_link = roots[0]
    note = ""
    if tip_link is None:
        if len(leaves) != 1 and TOOL_FRAME not in leaves:
            raise ChainError("tip_link", f"the URDF has {len(leaves)} leaf links ({', '.join(leaves[:6])}); name one")
        tip_link = leaves[0] if len(leaves) == 1 else TOOL_FRAME
        if len(leaves) > 1:
            note = (f"robot.tip_link: {TOOL_FRAME} (the ROS-Industrial tool frame) of the URDF's {len(leaves)} leaf "
                    f"links ({', '.join(leaves[:6])}); give robot.tip_link to choose another")
    for field_name, link in (("base_link", base_link), ("tip_link", tip_link)):
        if link not in links:
            raise ChainError(field_name, f"no link {link!r} in the URDF (links: {', '.join(sorted(links)[:8])})")
    path_joints = []
    link = tip_link
    while link != base_link:
        if link not in by_child or len(path_joints) > len(by_child):  # the second: a loop of links
            raise ChainError("tip_link", f"link {tip_link!r} does not descend from base_link {base_link!r}")
        j = by_child[link]
        path_joints.append(j)
        link = j.parent
    joints = []
    pending = np.eye(4)
    for j in reversed(path_joints):
        origin = np.eye(4) if j.origin is None else np.asarray(j.origin, float)
        if j.type == "fixed":
            pending = pending @ origin
            continue
        if j.type in ("floating", "planar"):
            raise ChainError(f"joint {j.name!r}", f"a {j.type} joint cannot be part of a serial arm here")
        if getattr(j, "mimic", None) is not None:
            raise ChainError(f"joint {j.name!r}", "mimic joints are not supported")
        axis = np.array([1.0, 0.0, 0.0]) if j.axis is None else np.asarray(j.axis, float)
        if not np.all(np.isfinite(axis)) or np.linalg.norm(axis) < 1e-9:
            raise ChainError(f"joint {j.name!r}", f"axis {axis.tolist()} is not a direction")
        lim = j.limit
        speed = (speeds or {}).get(j.name, None if lim is None else lim.velocity)
        if speed is None or not speed > 0 or not math.isfinite(speed):
            raise ChainError(f"joint {j.name!r}", "needs <limit velocity=...> > 0 (the rated speed: the scaling Q), "
                                                  "or robot.speed_override_rad_s for it in the config")
        if j.type == "continuous":
            kind, lo, hi = CONTINUOUS, -math.inf, math.inf
        elif lim is None:
            raise ChainError(f"joint {j.name!r}", "a revolute or prismatic joint needs a <limit> (the URDF "
                                                  "specification requires one)")
        else:
            kind = PRISMATIC if j.type == "prismatic" else REVOLUTE
            # the URDF specification (and urdfdom, Pinocchio): a missing lower or upper is 0
            lo = 0.0 if lim.lower is None else float(lim.lower)
            hi = 0.0 if lim.upper is None else float(lim.upper)
            if not lo <= hi:
                raise ChainError(f"joint {j.name!r}", f"limit lower {lo} > upper {hi}")
        joints.append(Joint(j.name, pending @ origin, axis / np.linalg.norm(axis), kind, lo, hi, float(speed)))
        pending = np.eye(4)
    if not joints:
        raise ChainError("tip_link", f"no movable joint between {base_link!r} and {tip_link!r}")
    return ChainSpec(tuple(joints), pending, note)


#: The largest URDF read (a robot description with every mesh inlined is a few MB).
MAX_URDF_BYTES = 64 * 2 ** 20
#: Physical bounds of what a URDF of an arm may say: a joint origin within 10 m of its parent, an angle
#: within two turns, a joint limit within 10 m or two turns, a rated speed up to 100 rad/s or m/s.
MAX_URDF_LENGTH_M = 10.0
MAX_URDF_ANGLE_RAD = 4 * math.pi
MAX_URDF_SPEED = 100.0


def parse_urdf_strictly(path):
    """The URDF's XML tree, parsed strictly (lxml's recovering parser, which yourdfpy falls back to, drops
    what it cannot read and computes another arm): a file that is not a regular, well-formed XML file of at
    most MAX_URDF_BYTES is a ChainError with the line and column."""
    import stat

    from lxml import etree

    p = Path(path)
    try:
        st = p.stat()
    except OSError as exc:
        raise ChainError(str(path), f"cannot be read ({exc.strerror or exc})") from None
    if not stat.S_ISREG(st.st_mode):
        raise ChainError(str(path), "is not a regular file")
    if st.st_size > MAX_URDF_BYTES:
        raise ChainError(str(path), f"{st.st_size:,} bytes, more than a URDF has ({MAX_URDF_BYTES:,})")
    parser = etree.XMLParser(recover=False, resolve_entities=False, no_network=True, huge_tree=False)
    try:
        return etree.parse(str(p), parser)
    except etree.XMLSyntaxError as exc:
        line, col = exc.position
        msg = exc.msg.split(f", line {line}")[0]
        raise ChainError(str(path), f"not a readable URDF: line {line}, column {col}: {msg} "
                                    f"(not well-formed XML)") from None


def _numbers(text: str | None, n: int, what: str) -> list[float]:
    try:
        values = [float(v) for v in (text or "").split()]
    except ValueError:
        raise ChainError(what, f"{text!r} is not {n} number(s)") from None
    if len(values) != n:
        raise ChainError(what, f"{text!r} is not {n} number(s)")
    return values


def check_urdf_numbers(tree) -> None:
    """Every number surgopt reads from a URDF is finite and physically bounded: each joint's origin xyz
    (m) and rpy (rad), axis (a direction), limit lower/upper (rad or m) and velocity (rad/s or m/s); else a
    ChainError naming the joint, element and attribute (and its line)."""
    for joint in tree.getroot().iter("joint"):
        name = joint.get("name", "?")
        where = f"joint {name!r} (line {joint.sourceline})"
        for el, attr, n, bound in (("origin", "xyz", 3, MAX_URDF_LENGTH_M), ("origin", "rpy", 3, MAX_URDF_ANGLE_RAD),
                                   ("axis", "xyz", 3, None)):
            e = joint.find(el)
            if e is None or e.get(attr) is None:
                continue
            values = _numbers(e.get(attr), n, f"{where} <{el} {attr}>")
            if not all(math.isfinite(v) for v in values):
                raise ChainError(f"{where} <{el} {attr}>", f"{e.get(attr)!r} is not finite")
            if bound is not None and max(abs(v) for v in values) > bound:
                raise ChainError(f"{where} <{el} {attr}>", f"{e.get(attr)!r} is beyond {bound:g} "
                                                           f"({'m' if attr == 'xyz' else 'rad'}): not an arm's")
        lim = joint.find("limit")
        if lim is None:
            continue
        prismatic = joint.get("type") == "prismatic"
        for attr, bound in (("lower", MAX_URDF_LENGTH_M if prismatic else MAX_URDF_ANGLE_RAD),
                            ("upper", MAX_URDF_LENGTH_M if prismatic else MAX_URDF_ANGLE_RAD),
                            ("velocity", MAX_URDF_SPEED)):
            if lim.get(attr) is None:
                continue
            (v,) = _numbers(lim.get(attr), 1, f"{where} <limit {attr}>")
            if not math.isfinite(v) or abs(v) > bound:
                raise ChainError(f"{where} <limit {attr}>", f"{lim.get(attr)!r} is not finite or beyond {bound:g}")


def _first_line(exc: Exception) -> str:
    text = str(exc).strip()
    return text.splitlines()[0] if text else type(exc).__name__


def frames_at(spec: ChainSpec, q) -> list[np.ndarray]:
    """Each joint's frame (before its own motion) in the base frame at joint values ``q`` (missing ones 0)."""
    out, t = [], np.eye(4)
    q = list(q) + [0.0] * (len(spec.joints) - len(q))
    for j, v in zip(spec.joints, q):
        t = t @ j.origin
        out.append(t.copy())
        t = t @ axis_motion(j.axis, j.kind, v)
    return out


def chain_transform(spec: ChainSpec, q) -> np.ndarray:
    """Base -> tip-link transform at joint values q (every joint, in order): the plain product."""
    t = np.eye(4)
    for j, v in zip(spec.joints, q, strict=True):
        t = t @ j.origin @ axis_motion(j.axis, j.kind, v)
    return t @ spec.tail


def _align_z(axis: np.ndarray) -> np.ndarray:
    """A rotation (4x4) taking e_z to the unit ``axis``."""
    z = np.array([0.0, 0.0, 1.0])
    v = np.cross(z, axis)
    s, c = np.linalg.norm(v), float(z @ axis)
    t = np.eye(4)
    if s < 1e-15:
        if c < 0:
            t[:3, :3] = np.diag([1.0, -1.0, -1.0])
        return t
    k = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]]) / s
    t[:3, :3] = np.eye(3) + s * k + (1 - c) * (k @ k)
    return t


def tool_transform(tool_length_m: float, tool_axis=(0.0, 0.0, 1.0), tool_offset_m=(0.0, 0.0, 0.0)) -> np.ndarray:
    """Tip link -> tool frame: origin at the tip (offset + length along the axis), z along the tool."""
    a = np.asarray(tool_axis, float)
    a = a / np.linalg.norm(a)
    t = _align_z(a)
    t[:3, 3] = np.asarray(tool_offset_m, float) + tool_length_m * a
    return t


def reduce_chain(spec: ChainSpec, locked: dict[str, float], tool: np.ndarray, speeds: dict[str, float] | None = None,
                 limits: dict[str, tuple[float, float]] | None = None):
    """The kernel's ``Chain`` (and the active joints' names): ``locked`` joints (name -> value, rad or m)
    folded into the fixed transforms, each active joint's axis turned onto z, ``tool`` appended.

    ``speeds``/``limits`` override the spec's per joint (rad/s, rad). Exactly five joints must remain.
    """
    names = spec.names
    for n in locked:
        if n not in names:
            raise ChainError("locked_joints_deg", f"no joint {n!r} (joints: {', '.join(names)})")
    active = [j for j in spec.joints if j.name not in locked]
    if len(active) != 5:
        raise ChainError("locked_joints_deg", f"{len(active)} joints remain active ({', '.join(j.name for j in active)}); "
                                              f"the RCM study needs exactly five: lock {len(active) - 5} more"
                         if len(active) > 5 else f"only {len(active)} joints remain active; the RCM study needs five")
    for j in active:
        lo, hi = (limits or {}).get(j.name, (j.lower, j.upper))
        if not lo < hi:
            raise ChainError(f"joint {j.name!r}", f"cannot move: its limits are [{lo:g}, {hi:g}] (a URDF <limit> "
                                                  f"without lower/upper reads as 0, as the URDF specification "
                                                  f"says); lock it or give its range")
    fixed = []  # P_0..P_5
    pending = np.eye(4)
    prev_align_t = np.eye(4)
    for j in spec.joints:
        if j.name in locked:
            pending = pending @ j.origin @ axis_motion(j.axis, j.kind, locked[j.name])
            continue
        align = _align_z(j.axis)
        fixed.append(prev_align_t @ pending @ j.origin @ align)
        prev_align_t = align.T.copy()
        pending = np.eye(4)
    fixed.append(prev_align_t @ pending @ spec.tail @ tool)
    speeds = speeds or {}
    limits = limits or {}
    lower = np.array([limits.get(j.name, (j.lower, j.upper))[0] for j in active], float)
    upper = np.array([limits.get(j.name, (j.lower, j.upper))[1] for j in active], float)
    chain = Chain(rot=np.array([f[:3, :3] for f in fixed]), pos=np.array([f[:3, 3] for f in fixed]),
                  prismatic=np.array([1.0 if j.kind == PRISMATIC else 0.0 for j in active]),
                  lower=lower, upper=upper,
                  qdot_max=np.array([speeds.get(j.name, j.max_speed) for j in active], float))
    return chain, tuple(j.name for j in active)
