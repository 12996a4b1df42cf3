"""The helical test path and the P-controller kernel (surgopt/kinematics/rcm_track.py)."""
import math

import numpy as np

import reference as ref
from surgopt.config import load_embedded
from surgopt.kinematics import rcm_track as K
from surgopt.kinematics.serial_chain import Chain, kernel_arrays, rcm_walk
from surgopt.robots import pa10_7c
from surgopt.studies.rcm_grid import study as G
from surgopt.studies.rcm_track import study as S


def test_the_papers_path_length_and_speeds():
    """2.5 turns at a 2 mm margin in the 50 mm cube over 10 s, cubic: 364 mm, 36.4 mm/s mean, 54.6 peak
    (Sec. IV-B), at rest at both ends, inside the cube."""
    t, p, speed = K.helix_path((0.0, 0.0, -0.1), 0.05, 0.002, 2.5, 10.0, 1000.0, "cubic")
    assert t.shape == (10001,) and p.shape == (10001, 3)
    length = np.linalg.norm(np.diff(p, axis=0), axis=1).sum()
    assert abs(length * 1e3 - 364.2) < 0.05 and abs(K.helix_length_m(0.05, 0.002, 2.5) - length) < 1e-6
    assert abs(length / 10.0 * 1e3 - 36.4) < 0.05
    assert abs(speed.max() * 1e3 - 54.6) < 0.05 and abs(t[np.argmax(speed)] - 5.0) < 1e-9
    assert speed[0] == 0 and speed[-1] == 0
    fd = np.linalg.norm(np.diff(p, axis=0), axis=1) * 1000.0  # speed from the samples
    assert np.abs(fd - 0.5 * (speed[1:] + speed[:-1])).max() < 1e-5
    assert np.abs(p[:, :2]).max() <= 0.025 and p[:, 2].max() <= -0.075 and p[:, 2].min() >= -0.125
    assert np.allclose(p[0], [0.023, 0.0, -0.077]) and np.allclose(p[-1][2], -0.123)
    # the ratio that pins the cubic: 1.5; the quintic's 1.875
    _, _, sq = K.helix_path((0, 0, -0.1), 0.05, 0.002, 2.5, 10.0, 1000.0, "quintic")
    assert abs(speed.max() / speed.mean() - 1.5) < 1e-3 and abs(sq.max() / sq.mean() - 1.875) < 1e-3


def _sliders():
    """Five prismatic joints along the base z axis: the tip's z is the sum of the joints (tip error =
    joint error for a reference that moves joint 1 only)."""
    eye = np.tile(np.eye(3), (6, 1, 1))
    return Chain(rot=eye, pos=np.zeros((6, 3)), prismatic=np.ones(5), lower=np.full(5, -np.inf),
                 upper=np.full(5, np.inf), qdot_max=np.full(5, 0.2))


def _ramp(v, m=3001, dt=1e-3):
    """Joint 1 of the sliders at v t, and the tip path it makes."""
    t = np.arange(m) * dt
    q_ref = np.zeros((m, 5))
    q_ref[:, 0] = v * t
    p_ref = np.zeros((m, 3))
    p_ref[:, 2] = v * t
    return q_ref, p_ref


def _run(chain, q_ref, p_ref, gain, lag=0.0, scale=1.0, dt=1e-3):
    trace = np.zeros((p_ref.shape[0], 6))
    out = K.track(kernel_arrays(chain), q_ref, 1, p_ref, np.array([0.0, 0.0, 10.0]), dt, gain, lag, True, scale, 1, trace)
    return out, trace


def test_a_slow_ramp_tracks_to_the_p_lag_error_of_the_closed_form():
    """q_ref = v t in one joint, never saturating: e_k = (v / K)(1 - (1 - K dt)^k) exactly."""
    chain = _sliders()
    v, gain, dt, m = 0.01, 8.0, 1e-3, 3001
    (e_max, e_mean, *_), trace = _run(chain, *_ramp(v, m, dt), gain)
    want = (v / gain) * (1 - (1 - gain * dt) ** np.arange(m))
    np.testing.assert_allclose(trace[:, 4], want, rtol=1e-9, atol=1e-15)
    assert abs(e_max - want.max()) < 1e-12 and abs(e_max - v / gain) < 1e-6


def test_a_saturating_ramp_does_not():
    """Faster than the rated speed: the error grows without bound instead of settling at v / K."""
    chain = _sliders()
    v, gain = 0.5, 8.0
    (e_max, _, _, _, peak, sat_s), trace = _run(chain, *_ramp(v), gain)
    assert e_max > 10 * v / gain and peak[0] == 1.0 and sat_s > 2.9
    # once saturated the joint moves at 0.2 m/s: the error grows at v - 0.2
    slope = (trace[-1, 4] - trace[-1001, 4]) / 1.0
    assert abs(slope - (v - 0.2)) < 1e-9


def test_kernel_equals_the_plain_loop_on_the_pa10():
    """The numba loop against tests/reference.py's Python loop (textbook DH forward kinematics), with a
    velocity lag and a saturation that binds, on one second of the paper's path at its best RCM."""
    cfg = load_embedded(S.DEFAULT_CONFIG, S.Config)
    tr = cfg.track.model_copy(update={"duration_s": 1.0, "velocity_lag_s": 0.02, "saturation_speed_scale": 0.05,
                                      "ik_every_steps": 1})
    cfg = cfg.model_copy(update={"track": tr})
    chain, names, seed = cfg.robot.chain()
    rcm = G.candidate_rcms(cfg, G.candidate_xyz(cfg)[7:8])[0]
    _, off, _ = S.reference_path(cfg)
    walk = rcm_walk(chain, rcm, off, seed, start=np.array([0.0, 0.0, -0.1]))
    assert walk["n_unreachable"] == 0
    p_ref = np.ascontiguousarray(rcm + off)
    trace = np.zeros((off.shape[0], 6))
    e_max, e_mean, r_max, r_mean, peak, sat_s = K.track(kernel_arrays(chain), walk["q"], 1, p_ref, rcm, 1e-3, 10.74, 0.02,
                                                         True, 0.05, 1, trace)
    def fk(q5):
        return ref.pa10_tool_tip(q5, pa10_7c.LINKS_BIELEFELD_M, pa10_7c.TOOL_LENGTH_M)

    qmax = np.array([pa10_7c.MAX_JOINT_SPEED_RAD_S[n] for n in pa10_7c.ACTIVE_JOINTS])
    want_e, want_r, errs = ref.p_control_track(fk, walk["q"], p_ref, rcm, 1e-3, 10.74, 0.02, qmax, 0.05)
    assert sat_s > 0.1  # the saturation binds
    np.testing.assert_allclose(trace[:, 4], errs, rtol=1e-9, atol=1e-13)
    assert math.isclose(e_max, want_e, rel_tol=1e-9) and math.isclose(r_max, want_r, rel_tol=1e-9)
