"""Trajectory tracking about an RCM (Locke & Patel 2007, Sec. IV): the helical test path and the
joint-level proportional controller of the experiment.

``helix_path`` (numpy): the reference tip path. A circular helix about the workspace cube's vertical
axis from its top to its bottom, ``turns`` turns of radius (side / 2 - margin) over a height
(side - 2 margin), followed at a speed set by a time scaling s(t / T) of its arc length. The paper gives
the average and peak tip speeds, 36.4 and 54.6 mm/s over 10 s: the ratio 1.5 is exactly the cubic
scaling s = 3 u^2 - 2 u^3 (peak s' = 1.5, at rest at both ends; the quintic's ratio is 1.875), and the
length 364 mm with a helix inside the 50 mm cube that approaches all its faces is 2.5 turns at a 2 mm
margin (2 turns would need a radius beyond the cube, 3 turns leave 6 mm): 364.2 mm (docs/reproduction.md).

``track`` (numba): per control step (1 kHz), the commanded joint velocity K (q_ref - q) of a
proportional joint controller on the RCM-constrained IK of the reference, each joint saturated at its
rated speed (the same Q as the GII), optionally through a first-order velocity lag (the robot's own
velocity loop), integrated; the tool tip and the tool line's distance from the RCM by forward kinematics
of the chain (``serial_chain.chain_frames``).
"""
from __future__ import annotations

import numpy as np

from surgopt.jit import CONTRACT, njit
from surgopt.kinematics.serial_chain import N_ACTIVE, chain_frames

#: Time scalings s(u), u = t / T in [0, 1]: s(0) = 0, s(1) = 1, s'(0) = s'(1) = 0.
TIME_SCALINGS = ("cubic", "quintic")


def time_scaling(u, kind: str):
    """(s, ds/du) of the named time scaling: cubic 3u^2 - 2u^3 (peak/mean speed 1.5), quintic
    10u^3 - 15u^4 + 6u^5 (1.875; also at rest in acceleration)."""
    u = np.asarray(u, dtype=np.float64)
    if kind == "cubic":
        return u * u * (3.0 - 2.0 * u), 6.0 * u * (1.0 - u)
    if kind == "quintic":
        return u ** 3 * (10.0 + u * (-15.0 + 6.0 * u)), 30.0 * u * u * (1.0 - u) ** 2
    raise ValueError(f"time scaling {kind!r} is not one of {TIME_SCALINGS}")


def helix_length_m(side_m: float, margin_m: float, turns: float) -> float:
    """Arc length of the helix: radius side/2 - margin, height side - 2 margin, ``turns`` turns."""
    r, h = side_m / 2 - margin_m, side_m - 2 * margin_m
    return float(np.hypot(2 * np.pi * turns * r, h))


def helix_path(centre, side_m: float, margin_m: float, turns: float, duration_s: float, rate_hz: float,
               scaling: str = "cubic"):
    """(t (M,), p (M, 3), speed (M,)) of the reference path sampled at the control rate, M = T f + 1.

    Worked example (tests): the paper's cube (50 mm, centred 100 mm below the RCM), 2.5 turns, 2 mm
    margin, 10 s, cubic: length 364.2 mm, mean speed 36.42 mm/s, peak 54.63 mm/s at t = 5 s.
    """
    n = int(round(duration_s * rate_hz))
    t = np.arange(n + 1) / rate_hz
    s, ds = time_scaling(t / duration_s, scaling)
    r, h = side_m / 2 - margin_m, side_m - 2 * margin_m
    theta = 2 * np.pi * turns * s
    c = np.asarray(centre, dtype=np.float64)
    p = np.stack([c[0] + r * np.cos(theta), c[1] + r * np.sin(theta), c[2] + h / 2 - h * s], axis=1)
    speed = helix_length_m(side_m, margin_m, turns) * ds / duration_s
    return t, p, speed


@njit(**CONTRACT)
def track(chain_arrays, q_ref, every, p_ref, rcm, dt, gain, lag_s, saturate, speed_scale, trace_every, trace):
    """Simulate the joint-level P controller along ``q_ref`` (K, 5: the IK of every ``every``-th
    control step, linearly interpolated between) against the tip path ``p_ref`` (M, 3), M = (K-1) every + 1:

        qdot_cmd(k) = gain (q_ref(t_k) - q_k), clipped to +-speed_scale qdot_max;  qdot_k = lag(qdot_cmd);
        q_{k+1} = q_k + qdot_k dt.

    Starts at rest on the reference. Returns (max tip error, mean tip error, max RCM error, mean RCM
    error (m), peak |qdot| / qdot_max per joint (5,), seconds with any joint saturated); every
    ``trace_every``-th step's tip and error go to ``trace`` (rows t, x, y, z, tip error, RCM error).
    """
    rot, pos, prismatic, lower, upper, qdot_max = chain_arrays
    axes = np.empty((N_ACTIVE, 3))
    origins = np.empty((N_ACTIVE, 3))
    trig = np.zeros((4, N_ACTIVE))
    trig[2, :] = np.nan
    q = q_ref[0].copy()
    qdot = np.zeros(N_ACTIVE)
    peak = np.zeros(N_ACTIVE)
    m = p_ref.shape[0]
    e_max = e_sum = r_max = r_sum = 0.0
    sat_steps = 0
    alpha = 1.0 if lag_s <= 0.0 else dt / (lag_s + dt)  # backward-Euler first-order lag
    for k in range(m):
        # tip and tool line at the current joints
        r = chain_frames(rot, pos, prismatic, q, axes, origins, trig)
        kx, ky, kz, px, py, pz = r[2], r[5], r[8], r[9], r[10], r[11]
        ex, ey, ez = px - p_ref[k, 0], py - p_ref[k, 1], pz - p_ref[k, 2]
        e = np.sqrt(ex * ex + ey * ey + ez * ez)
        cx, cy, cz = rcm[0] - px, rcm[1] - py, rcm[2] - pz
        s = cx * kx + cy * ky + cz * kz
        dx, dy, dz = cx - s * kx, cy - s * ky, cz - s * kz
        d = np.sqrt(dx * dx + dy * dy + dz * dz)
        e_max = max(e_max, e)
        r_max = max(r_max, d)
        e_sum += e
        r_sum += d
        if trace_every > 0 and k % trace_every == 0:
            row = k // trace_every
            trace[row, 0], trace[row, 1], trace[row, 2], trace[row, 3] = k * dt, px, py, pz
            trace[row, 4], trace[row, 5] = e, d
        if k == m - 1:
            break
        # the reference joints at step k (interpolated), the P command, saturation, lag, integration
        j = k // every
        f = (k - j * every) / every
        saturated = False
        for i in range(N_ACTIVE):
            qr = q_ref[j, i] if f == 0.0 else q_ref[j, i] + f * (q_ref[j + 1, i] - q_ref[j, i])
            cmd = gain * (qr - q[i])
            cap = speed_scale * qdot_max[i]
            if saturate and abs(cmd) > cap:
                cmd = cap if cmd > 0 else -cap
                saturated = True
            qdot[i] += alpha * (cmd - qdot[i])
            peak[i] = max(peak[i], abs(qdot[i]) / qdot_max[i])
            q[i] += qdot[i] * dt
        sat_steps += 1 if saturated else 0
    return e_max, e_sum / m, r_max, r_sum / m, peak, sat_steps * dt
