"""Raven IV common workspace: the public driver of the ``surgopt.kinematics.raven`` kernels.

From port layout and design lists to the kernels' named tuples, and back to per-design metrics:
ports and shoulder axes of every arm (``arms``), the cone-angle interval of each (alpha, beta,
Iso_min) (``cone_angle_intervals``), the metrics of many geometries at once with identical ones
shared (``evaluate_many``), and the plane fields of one design for figures (``design_fields``).
Lengths mm, angles in degrees at this interface (radians inside the kernels).
"""
from __future__ import annotations

import functools
import itertools
import math
import threading
from typing import NamedTuple, Sequence

import numpy as np

from surgopt.kinematics.raven import cone_angle, theta2_interval
from surgopt.kinematics.raven_shoulder import shoulder_design, shoulder_fields, shoulder_range, theta1_row
from surgopt.kinematics.raven_plane import (
    DesignGrid,
    PlaneGrid,
    covering_plane_grid,
    evaluate_geometries,
    node_margins,
    plane_node_bounds,
)


class ArmLayout(NamedTuple):
    """Where the ports are and how each shoulder axis points at phi = 0 (the paper's Fig. 3 choices)."""

    n_arms: int
    ports_mm: tuple | None  # ((x, y), ...) per arm, or None: from bx, by
    left_arms: tuple | None  # mirrored (left) arms, or None: arms 1 and 3
    shoulder_tilt_deg: float  # axis 1 from vertical at phi = 0, outward
    shoulder_tilt_toward: str  # "x" or "y"
    mirror_left_phi: bool  # left arms turn by the mirror image of the right arms' rotation
    phi_order: str = "zyx"  # R = Rz(phi_z) Ry(phi_y) Rx(phi_x) ("zyx") or Rx Ry Rz ("xyz")
    mirror_plane: str = "yz"  # the plane the left arms mirror the right ones in: "yz" (x -> -x) or "xz"
    theta1_zero_toward: str = "y"  # x0 (theta1's zero) before tilt and phi: world "x", "y", "-x" or "-y"


def cos_sin_deg(deg: float) -> tuple[float, float]:
    """cos and sin of an angle in degrees, exact at multiples of 90 (cos 90 deg is 0, not 6e-17)."""
    if deg % 90 == 0:
        return ((1.0, 0.0), (0.0, 1.0), (-1.0, 0.0), (0.0, -1.0))[int(deg // 90) % 4]
    return math.cos(math.radians(deg)), math.sin(math.radians(deg))


def rotation_deg(axis: int, deg: float) -> np.ndarray:
    """Rotation matrix about the x (0), y (1) or z (2) axis by ``deg`` degrees."""
    c, s = cos_sin_deg(deg)
    if axis == 0:
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    if axis == 1:
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def arms(layout: ArmLayout, phi_x: float, phi_y: float, phi_z: float, bx: float, by: float):
    """Ports (n, 3) and shoulder-axis directions (n, 3) in the world frame (``arm_frames`` without x0)."""
    ports, axes, _ = arm_frames(layout, phi_x, phi_y, phi_z, bx, by)
    return ports, axes


#: World unit vectors of ``ArmLayout.theta1_zero_toward``.
ZERO_DIRECTIONS = {"x": (1.0, 0.0, 0.0), "-x": (-1.0, 0.0, 0.0), "y": (0.0, 1.0, 0.0), "-y": (0.0, -1.0, 0.0)}


def arm_frames(layout: ArmLayout, phi_x: float, phi_y: float, phi_z: float, bx: float, by: float):
    """Ports (n, 3), shoulder-axis directions z0 (n, 3) and theta1's zero directions x0 (n, 3), world frame.

    Ports: 4 arms at (-bx/2, +by/2), (+bx/2, +by/2), (-bx/2, -by/2), (+bx/2, -by/2)
    (arms 1-4, left arms 1 and 3), 2 arms at (-+bx/2, 0), 1 arm at 0.
    Axis 1 at phi = 0: vertical (out of the patient), tilted outward by
    ``shoulder_tilt_deg`` along x (away from the other side's arms) or along y
    (away from the other pair), per ``shoulder_tilt_toward`` (a negative tilt leans inward); then
    R = Rz(phi_z) Ry(phi_y) Rx(phi_x) about the port (``phi_order = "zyx"``; "xyz": Rx Ry Rz), for left
    arms when ``mirror_left_phi`` the mirror image M R M of a right arm's rotation: in the y-z plane
    (``mirror_plane = "yz"``, x -> -x) phi_y and phi_z change sign, in the x-z plane phi_x and phi_z.
    x0 (theta1 = 0: the elbow axis z1 in the plane of z0 and x0, Table I's DH) is the world direction
    ``theta1_zero_toward`` as seen by arm 2 (front right), mirrored as the tilt is (x negated for left arms;
    with the tilt along y, y negated for the rear row), carried by the same tilt (a rotation about the
    horizontal axis perpendicular to the tilt direction) and the same R as z0: it stays perpendicular to
    z0, and at phi = 0 the arms' frames are mirror images of each other, as their tilts are.
    """
    if layout.ports_mm is not None:
        ports = [(p[0], p[1]) for p in layout.ports_mm]
    elif layout.n_arms == 4:
        ports = [(-bx / 2, by / 2), (bx / 2, by / 2), (-bx / 2, -by / 2), (bx / 2, -by / 2)]
    elif layout.n_arms == 2:
        ports = [(-bx / 2, 0.0), (bx / 2, 0.0)]
    else:
        ports = [(0.0, 0.0)]
    P = np.array([[x, y, 0.0] for x, y in ports])
    key = (float(phi_x), float(phi_y), float(phi_z), tuple(bool(y >= 0) for y in P[:, 1]))
    try:
        A, X = _shoulder_frames(layout, *key)
    except TypeError:  # a layout built with lists is not hashable
        A, X = _shoulder_frames.__wrapped__(layout, *key)
    return P, A.copy(), X.copy()


@functools.lru_cache(maxsize=4096)
def _shoulder_frames(layout: ArmLayout, phi_x: float, phi_y: float, phi_z: float, front: tuple):
    """z0 and x0 of every arm (``arm_frames``), which depend on the ports only through the row each
    is in (``front``: port y >= 0), so a sweep's bx, by values share them (cached: 16 of every 17
    calls in Table II)."""
    A, X = np.empty((layout.n_arms, 3)), np.empty((layout.n_arms, 3))
    zero = np.array(ZERO_DIRECTIONS[layout.theta1_zero_toward])
    for i, is_left in enumerate(left_arms(layout)):
        side = np.array([-1.0 if is_left else 1.0, 1.0, 1.0])  # x0's mirror: the left arms' x negated ...
        if layout.shoulder_tilt_toward == "x":
            out = -1.0 if is_left else 1.0
            tilt = rotation_deg(1, out * layout.shoulder_tilt_deg)  # e_z -> (out st, 0, ct)
        else:
            out = 1.0 if front[i] else -1.0
            tilt = rotation_deg(0, -out * layout.shoulder_tilt_deg)  # e_z -> (0, out st, ct)
            side[1] = out  # ... and, tilted along y, the rear row's y (the tilt's own symmetry)
        m = -1.0 if (is_left and layout.mirror_left_phi) else 1.0
        mx, my = (1.0, m) if layout.mirror_plane == "yz" else (m, 1.0)
        rx, ry, rz = rotation_deg(0, mx * phi_x), rotation_deg(1, my * phi_y), rotation_deg(2, m * phi_z)
        R = rz @ ry @ rx if layout.phi_order == "zyx" else rx @ ry @ rz
        A[i] = R @ tilt[:, 2]
        X[i] = R @ (tilt @ (zero * side))
    A.flags.writeable = X.flags.writeable = False
    return A, X


def cone_angle_intervals(alphas_rad, betas_rad, iso_mins, theta2_range_deg) -> DesignGrid:
    """The ``DesignGrid`` of these designs: per (alpha, beta, Iso_min) the interval of psi (eq. 22) over
    the theta2 range narrowed by Iso_min (``theta2_interval``)."""
    lo2, hi2 = (math.radians(v) for v in theta2_range_deg)
    al, be, iso = (np.asarray(v, dtype=np.float64) for v in (alphas_rad, betas_rad, iso_mins))
    shape = (len(al), len(be), len(iso))
    psi_lo, psi_hi, has_interval = np.zeros(shape), np.zeros(shape), np.zeros(shape, bool)
    for (i, a), (j, b), (k, m) in itertools.product(enumerate(al), enumerate(be), enumerate(iso)):
        t_lo, t_hi, ok = theta2_interval(a, b, m, lo2, hi2)
        psi_lo[i, j, k], psi_hi[i, j, k], has_interval[i, j, k] = cone_angle(t_lo, a, b), cone_angle(t_hi, a, b), ok
    return DesignGrid(al, be, iso, psi_lo, psi_hi, has_interval)


@functools.lru_cache(maxsize=64)
def _design_grid(alphas_rad: tuple, betas_rad: tuple, iso_mins: tuple, theta2_range_deg: tuple) -> DesignGrid:
    """``cone_angle_intervals``, computed once per design list (every task of a sweep shares it)."""
    return cone_angle_intervals(alphas_rad, betas_rad, iso_mins, theta2_range_deg)


class _MetricsMemo:
    """Metrics of geometries already evaluated in this process, keyed by everything they depend on;
    cleared when it would grow past ``max_bytes``. Shared by the threads of the threads backend."""

    def __init__(self, max_bytes: int):
        self.max_bytes = max_bytes
        self.blocks: dict[bytes, np.ndarray] = {}
        self.lock = threading.Lock()

    def clear(self) -> None:
        with self.lock:
            self.blocks.clear()


#: 64 MB of metrics: bounded in bytes, so large design lists cannot grow it without bound.
MEMO = _MetricsMemo(64 * 2 ** 20)


def clear_memo() -> None:
    """Forget every memoised geometry (benchmarks and tests that time or check fresh evaluations)."""
    MEMO.clear()


def left_arms(layout: ArmLayout) -> np.ndarray:
    """Per arm, True for the mirrored (left) arms: ``layout.left_arms``, or arms 1 and 3."""
    left = layout.left_arms if layout.left_arms is not None else [i % 2 == 0 for i in range(layout.n_arms)]
    return np.array(left, dtype=np.bool_)


def evaluate_many(layout: ArmLayout, plane: PlaneGrid, theta2_range_deg: Sequence[float],
                  geometries, alphas_deg, betas_deg, isos, designs: DesignGrid | None = None,
                  theta1_range_deg: Sequence[float] | None = None) -> np.ndarray:
    """Metrics (G*A*B*I, 6) of every design of G geometries (phi_x, phi_y, phi_z, bx, by), geometry-major.

    Columns as ``evaluate_designs``: area_mm2, perimeter_mm, n_points, iso_sum, iso_min_actual, any.
    Geometries whose ports and shoulder axes come out identical share one
    evaluation: in this batch, and across batches of this process (a memo
    keyed by the exact ports, axes, plane and design lists). In the paper's
    Table II with horizontal shoulder axes along x, phi_x turns each axis
    about itself, so its five values give one geometry: 400 of the 2000 are
    distinct. ``designs``: ``cone_angle_intervals`` of these alphas, betas and
    Iso_mins, when already known (they do not depend on the geometry). ``theta1_range_deg``: the
    shoulder range [lo, hi] about each arm's zero direction (``arm_frames``), or None: unlimited.
    """
    per = len(alphas_deg) * len(betas_deg) * len(isos)
    rng = shoulder_range(theta1_range_deg)
    placed = [arm_frames(layout, *g) for g in geometries]
    shape = (len(placed), layout.n_arms, 3)
    ports = np.array([p for p, _, _ in placed], dtype=np.float64).reshape(shape) + 0.0  # -0.0 -> 0.0
    axes = np.array([a for _, a, _ in placed], dtype=np.float64).reshape(shape) + 0.0
    zero_axes = np.array([x for _, _, x in placed], dtype=np.float64).reshape(shape) + 0.0
    left = left_arms(layout)
    al = np.radians(np.asarray(alphas_deg, float))
    be = np.radians(np.asarray(betas_deg, float))
    iso = np.asarray(isos, float)
    context = np.concatenate([[plane.depth_mm, plane.step_mm, plane.d4_max_mm, *theta2_range_deg, len(al), len(be)],
                              al, be, iso]).tobytes()
    if rng.limited:  # theta1 depends on the zero directions and the arm sides too
        context += np.array(rng[1:], float).tobytes() + left.tobytes()
    keys = [context + ports[g].tobytes() + axes[g].tobytes() + (zero_axes[g].tobytes() if rng.limited else b"")
            for g in range(len(placed))]
    out = np.zeros((len(placed) * per, 6))
    todo: dict[bytes, list[int]] = {}
    with MEMO.lock:
        for g, key in enumerate(keys):
            if key in MEMO.blocks:
                out[g * per:(g + 1) * per] = MEMO.blocks[key]
            else:
                todo.setdefault(key, []).append(g)
    if not todo:
        return out
    first = [gs[0] for gs in todo.values()]
    if designs is None:
        designs = _design_grid(tuple(al), tuple(be), tuple(iso), tuple(float(v) for v in theta2_range_deg))
    fresh = np.zeros((len(first) * per, 6))
    plane = PlaneGrid(float(plane.depth_mm), float(plane.step_mm), float(plane.d4_max_mm))
    evaluate_geometries(np.ascontiguousarray(ports[first]), np.ascontiguousarray(axes[first]),
                        np.ascontiguousarray(zero_axes[first]), left, plane, designs, rng, fresh)
    with MEMO.lock:
        if (len(MEMO.blocks) + len(todo)) * fresh.itemsize * per * 6 > MEMO.max_bytes:
            MEMO.blocks.clear()
        for u, (key, gs) in enumerate(todo.items()):
            block = fresh[u * per:(u + 1) * per]
            MEMO.blocks[key] = block
            for g in gs:
                out[g * per:(g + 1) * per] = block
    return out


def design_fields(layout: ArmLayout, plane: PlaneGrid, theta2_range_deg, geometry, alpha_deg, beta_deg, iso_min,
                  theta1_range_deg=None):
    """Plane grid and membership margins of one design, per arm and common (for figures).

    Returns xs, ys (mm), ports (arms, 3), the per-arm margin (arms, nx, ny) and the common margin
    (nx, ny), computed by the sweep's own kernels (``plane_node_bounds``, ``node_margins``, and
    ``theta1_row`` when theta1 is limited) on a grid that covers every arm's reach. A margin is
    positive inside, zero on the boundary (mm-like).
    """
    ports, axes, zero_axes = arm_frames(layout, *geometry)
    ports, axes = np.ascontiguousarray(ports + 0.0), np.ascontiguousarray(axes + 0.0)
    zero_axes, left = np.ascontiguousarray(zero_axes + 0.0), left_arms(layout)
    rng = shoulder_range(theta1_range_deg)
    xs, ys = covering_plane_grid(ports, float(plane.depth_mm), float(plane.d4_max_mm), float(plane.step_mm))
    d = cone_angle_intervals([math.radians(alpha_deg)], [math.radians(beta_deg)], [iso_min], theta2_range_deg)
    c_lo, c_hi = math.cos(d.psi_hi_rad[0, 0, 0]), math.cos(d.psi_lo_rad[0, 0, 0])
    n = xs.size * ys.size

    def margin(arm):
        if not d.has_interval[0, 0, 0]:
            return np.full((xs.size, ys.size), -1.0)
        p, a = ports[arm], axes[arm]
        out = np.empty(n)
        node_margins(plane_node_bounds(xs, ys, float(plane.depth_mm), p, a, float(plane.d4_max_mm)), c_lo, c_hi, out)
        if rng.limited:
            t1 = np.empty(n)
            fields = shoulder_fields(xs, ys, float(plane.depth_mm), p, a, zero_axes[arm], left[arm])
            theta1_row(fields, 0, n, shoulder_design(math.radians(alpha_deg), math.radians(beta_deg), rng), t1)
            out = np.minimum(out, t1)
        return out.reshape(xs.size, ys.size)

    per_arm = np.stack([margin(slice(i, i + 1)) for i in range(len(ports))])
    return xs, ys, ports, per_arm, margin(slice(None))
