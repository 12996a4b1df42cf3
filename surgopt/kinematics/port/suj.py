"""The patient cart's setup joints (SUJ, ``robots/dvrk/suj.py``): forward kinematics from the DH data (S1), the Si's
family of docking orientations (S3), and what the inverses share (the tie rule, the grids' steps).

The inverses run as the rows run them, many poses at once: the Classic PSM's S2 and the Classic ECM's S4 jitted in
``suj_batch``, the Si's S3 and S7 in ``si_docking.si_solutions``; every view docks a layout with those too (issue 53:
one implementation in production). Their plain Python twin, pose by pose, is ``tests/reference.py``
(``classic_psm_ik``, ``si_ik``, ``ecm_classic_dock``), which the tests and ``benchmarks/bench_cart.py`` hold them to.

Every SUJ is a vertical column (prismatic), then revolute joints about vertical axes (a planar chain: they
set the x, y and the yaw psi of their last frame), then either two more joints (the Classic's: they tilt the
arm) or fixed links (the Si's: the arm's tilt is built in). So

    T_world_rcm = W  H(column, planar joints)  G(wrist joints)  T_tip,                         (S1)

with W = world_origin_to_SUJ, H = Trans(x, y, z) Rz(psi) and G the rest (constant on the Si).

Classic PSM (S2, closed form): with M = R(W^-1 T) R_tip^T, the wrist's two axes are z and n = Rx(alpha_4) z
(alpha_4 = 1.5708 as the file writes it: n is 2e-6 off a right angle to z), so M = Rz(psi) Rot(n, q4)
Rz(q5 + offset_5), a Davenport decomposition: z.M z = c^2 + (1 - c^2) cos q4 with c = n.z gives q4 (two
signs), then psi and q5 from M's other columns; the planar chain's end point gives the two elbows of its first
two joints (the law of cosines) and the third closes the yaw; the column closes z. Up to 4 solutions.

Si PSM1, PSM2, ECM (S3): G is constant, so the base's orientation can only turn about the vertical: the
reachable docking orientations are R = Rz(psi) R_0, a one-parameter family (``si_orientation``); a pose off
the family is refused with the angle it is off by; on it, two elbow solutions. The Si PSM3 (S7) has four planar
joints for the same three degrees of freedom: its first is free, taken on a grid, the rest solved as above.

All in metres and radians.
"""
from __future__ import annotations

import math

import numpy as np


def mdh(alpha: float, a: float, theta: float, d: float) -> np.ndarray:
    """Modified (Craig) DH link transform Rx(alpha) Tx(a) Rz(theta) Tz(d)."""
    ca, sa, ct, st = math.cos(alpha), math.sin(alpha), math.cos(theta), math.sin(theta)
    return np.array([[ct, -st, 0.0, a], [st * ca, ct * ca, -sa, -sa * d], [st * sa, ct * sa, ca, ca * d],
                     [0.0, 0.0, 0.0, 1.0]])


def link(row, q: float) -> np.ndarray:
    """One ``chain.DhRow`` (modified) at joint value q: theta + q for a revolute joint, d + q for the column."""
    if row.prismatic:
        return mdh(row.alpha_rad, row.a_m, row.theta_offset_rad, row.d_m + q)
    return mdh(row.alpha_rad, row.a_m, row.theta_offset_rad + q, row.d_m)


def forward(suj, q) -> np.ndarray:
    """(S1) The arm's base (RCM) frame in the cart's world frame at SUJ joints ``q`` (m, rad)."""
    t = np.asarray(suj.world_to_suj, float)
    for row, v in zip(suj.links, q, strict=True):
        t = t @ link(row, v)
    for row in suj.fixed:
        t = t @ link(row, 0.0)
    return t @ np.asarray(suj.tip_to_tool, float)


def frames(suj, q) -> np.ndarray:
    """(k, 4, 4) The SUJ's frames from its base to the arm's base (RCM), in the cart's world frame: the SUJ's
    base, after each link, and the tool origin (what a figure draws and a collision check reads)."""
    t = np.asarray(suj.world_to_suj, float)
    out = [t]
    for row, v in zip(suj.links, q, strict=True):
        t = t @ link(row, v)
        out.append(t)
    for row in suj.fixed:
        t = t @ link(row, 0.0)
        out.append(t)
    out.append(t @ np.asarray(suj.tip_to_tool, float))
    return np.array(out)


def wrap(angle: float) -> float:
    """An angle in (-pi, pi]."""
    a = math.remainder(angle, 2 * math.pi)
    return math.pi if a == -math.pi else a


#: Solutions whose least margins differ by less than this (rad or m) are equally good: the first of them in the
#: solver's order (q4 ascending, then the elbow of positive sine) is the best, in the batch solvers (``suj_batch``,
#: ``si_docking``) and their plain twin (``tests/reference.py``), so all dock an arm with the same joints where
#: margins tie (the column's margin, shared by both elbows, often decides under the assumed full-turn ranges).
MARGIN_TIE = 1e-9


def _planar(suj, n_planar: int):
    """(the column's x offset A_c, its D, the planar joints' A (from the second on) and D, their offsets)."""
    col = suj.links[0]
    rows = suj.links[1:1 + n_planar]
    return col.a_m, col.d_m, [r.a_m for r in rows], [r.d_m for r in rows], [r.theta_offset_rad for r in rows]


def si_orientation(suj, yaw_rad: float) -> np.ndarray:
    """(S3) The one orientation an Si SUJ gives its arm's base at yaw ``yaw_rad`` of its planar chain, in the
    cart's world frame: R(W) Rz(yaw) R(fixed links) R_tip. Every reachable docking orientation is one of these."""
    g = np.eye(4)
    for row in suj.fixed:
        g = g @ link(row, 0.0)
    r = np.asarray(suj.world_to_suj, float)[:3, :3] @ mdh(0, 0, yaw_rad, 0)[:3, :3] @ g[:3, :3]
    return r @ np.asarray(suj.tip_to_tool, float)[:3, :3]


#: The Si PSM3's first planar joint, free (S7): its inverse takes it on a grid of this many values over a turn.
SI_REDUNDANT_STEPS = 360


#: The Classic ECM docking's grid (S4): the planar chain's heading, the aim's angle, theta4.
ECM_GRID_STEPS = (36, 36, 12)


