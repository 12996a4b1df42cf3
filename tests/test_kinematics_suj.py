"""The patient cart's setup joints (surgopt/robots/dvrk/suj.py, surgopt/kinematics/port/suj.py): forward kinematics
against the SUJ data typed again in tests/reference.py as textbook modified-DH products (the dVRK's sample
``simulated_position`` vectors and random joints), inverse kinematics by round trips (every solution's forward
kinematics is the pose to 1e-9 m and rad; random in-range joints recovered among the solutions) and the poses it
must refuse, each with its reason."""
import math

import numpy as np
import pytest

from surgopt.kinematics.port import suj as K
from surgopt.robots.dvrk import suj as D
from surgopt.robots.dvrk.platforms import PLATFORMS

import reference as REF
from reference import SUJ_REFERENCE, suj_forward_reference

RNG = np.random.default_rng(40)
ALL = sorted(SUJ_REFERENCE)
CLASSIC_PSMS = ["PSM1", "PSM2", "PSM3"]
SI_SOLVED = ["PSM1", "PSM2", "ECM"]


def _random_joints(suj, n):
    return [[RNG.uniform(lo, hi) for lo, hi in suj.ranges] for _ in range(n)]


def _same_joints(a, b, tol=1e-8):
    """Equal joint vectors, the revolute ones up to a whole turn."""
    return abs(a[0] - b[0]) < tol and all(abs(K.wrap(x - y)) < tol for x, y in zip(a[1:], b[1:]))


@pytest.mark.parametrize("cart, arm", ALL)
def test_forward_kinematics_is_the_textbook_product_at_the_sample_and_random_joints(cart, arm):
    suj = PLATFORMS[cart].suj(arm)
    for q in [D.SAMPLE_JOINTS[(cart, arm)], *_random_joints(suj, 20)]:
        np.testing.assert_allclose(K.forward(suj, q), suj_forward_reference(cart, arm, q), atol=1e-12)


@pytest.mark.parametrize("cart", ["classic", "si"])
def test_the_sample_positions_put_every_arms_rcm_over_one_patient(cart):
    """The files' sample joints dock the four arms around one patient: their RCMs within 0.6 m of each other,
    0.3-1.3 m in front of the cart and 0.35-1.1 m above its floor frame (a sanity check of the data as typed:
    a sign or a swapped row puts an arm metres away)."""
    rcms = np.array([K.forward(PLATFORMS[cart].suj(a), D.SAMPLE_JOINTS[(cart, a)])[:3, 3] for a in PLATFORMS[cart].sujs])
    spread = np.max(np.linalg.norm(rcms[:, None] - rcms[None], axis=2))
    assert spread < 0.6, rcms
    assert np.all((0.3 < rcms[:, 1]) & (rcms[:, 1] < 1.3) & (0.35 < rcms[:, 2]) & (rcms[:, 2] < 1.1)), rcms


@pytest.mark.parametrize("arm", CLASSIC_PSMS)
def test_classic_psm_ik_round_trips_and_recovers_random_joints(arm):
    """Every solution's forward kinematics is the pose (1e-9); the joints the pose was made from are among the
    solutions; the solutions within the ranges are the ones whose margin is >= 0 (the premise, where the ranges
    are the quoted ones, not full turns: some poses have solutions outside them too)."""
    suj = D.CLASSIC[arm]
    outside = 0
    for q in _random_joints(suj, 60):
        pose = K.forward(suj, q)
        answer = REF.classic_psm_ik(suj, pose)
        sols = answer.within + answer.outside
        assert any(_same_joints(s.joints, q) for s in answer.within)
        for s in sols:
            assert np.abs(K.forward(suj, s.joints) - pose).max() < 1e-9
            inside = all(lo <= v <= hi for v, (lo, hi) in zip(s.joints, suj.ranges))
            assert inside == (s.margin >= 0)
        outside += len(answer.outside)
    assert outside > 0 or arm == "PSM3"


@pytest.mark.parametrize("arm", SI_SOLVED)
def test_si_ik_round_trips_and_its_orientations_are_one_family(arm):
    """Si: every solution's forward kinematics is the pose; the random joints are recovered; the base's
    orientation is si_orientation at the planar chain's yaw (the one-parameter family of docking orientations
    the Si can give)."""
    suj = D.SI[arm]
    for q in _random_joints(suj, 60):
        pose = K.forward(suj, q)
        answer = REF.si_ik(suj, pose)
        assert any(_same_joints(s.joints, q) for s in answer.within)
        for s in answer.within + answer.outside:
            assert np.abs(K.forward(suj, s.joints) - pose).max() < 1e-9
        np.testing.assert_allclose(K.si_orientation(suj, sum(q[1:])), pose[:3, :3], atol=1e-12)


def test_the_si_psm3s_redundant_inverse_round_trips_and_recovers_its_joints_on_its_grid():
    """(S7) The Si PSM3: four planar joints for three planar degrees of freedom. Every solution's forward
    kinematics (the reference's, typed apart from the package) is the pose (1e-9); random joints whose first
    planar joint lies on the inverse's grid are among the solutions; the base's orientation is si_orientation at
    the chain's yaw; a pose the chain cannot reach at any value of its first joint is refused. Premise: several
    solutions per pose (the redundancy), every one in range under the assumed full turns."""
    suj = D.SI["PSM3"]
    steps = 72
    for q in _random_joints(suj, 20):
        q[1] = -math.pi + 2 * math.pi * RNG.integers(steps) / steps
        pose = suj_forward_reference("si", "PSM3", q)
        answer = REF.si_ik(suj, pose, steps=steps)
        assert len(answer.within) > 2 and not answer.outside
        assert any(_same_joints(s.joints, q) for s in answer.within)
        for s in answer.within:
            assert np.abs(suj_forward_reference("si", "PSM3", s.joints) - pose).max() < 1e-9
        np.testing.assert_allclose(K.si_orientation(suj, sum(q[1:])), pose[:3, :3], atol=1e-12)
    far = K.forward(suj, [0.3, 0.0, 0.0, 0.0, 0.0])
    far[:2, 3] += 3.0  # 3 m further than its links reach
    answer = REF.si_ik(suj, far, steps=steps)
    assert not answer.within and "out of reach" in answer.reason


def test_poses_the_suj_cannot_reach_are_refused_with_the_reason():
    """Out of the planar chain's reach; inside its reach only with a joint out of its range (the joint and the
    range named); an Si docking tilted off its family (the angle named)."""
    psm1 = D.CLASSIC["PSM1"]
    far = K.forward(psm1, D.SAMPLE_JOINTS[("classic", "PSM1")])
    far[:3, 3] += np.array([3.0, 0.0, 0.0])
    answer = REF.classic_psm_ik(psm1, far)
    assert not answer.within and "out of reach" in answer.reason
    # joints made with j1 and j2 past their ranges until every solution of the pose is outside them (seeded)
    for _ in range(200):
        q = [RNG.uniform(lo, hi) for lo, hi in psm1.ranges]
        q[1], q[2] = RNG.uniform(1.7, 2.5), RNG.uniform(0.5, 2.0)  # j1 past +90 deg, j2 past 0 deg
        answer = REF.classic_psm_ik(psm1, K.forward(psm1, q))
        if not answer.within:
            break
    assert not answer.within and answer.outside  # the premise: such a pose was found
    assert any(_same_joints(s.joints, q) for s in answer.outside)
    assert "outside its range" in answer.reason and "PSM1 SUJ j" in answer.reason
    si = D.SI["PSM1"]
    pose = K.forward(si, D.SAMPLE_JOINTS[("si", "PSM1")])
    tilt = np.eye(4)
    tilt[:3, :3] = [[1, 0, 0], [0, math.cos(0.1), -math.sin(0.1)], [0, math.sin(0.1), math.cos(0.1)]]
    answer = REF.si_ik(si, pose @ tilt)
    assert not answer.within and "tilted 5.73 deg" in answer.reason


def _ecm_batch(suj, yaw_rad, pitch_rad, origins, aims):
    """``suj_batch.ecm_margins`` (the jitted S4 the dock tables use) with ``ecm_classic_dock``'s arguments."""
    from surgopt.kinematics.port import suj_batch as B

    return B.ecm_margins(B.ecm_arrays(suj, yaw_rad, pitch_rad), np.ascontiguousarray(origins, float),
                         np.ascontiguousarray(aims, float), *K.ECM_GRID_STEPS)


ECM_SOLVERS = {"numpy": REF.ecm_classic_dock, "jitted": _ecm_batch}


def _ecm_bases(rng, n: int, spread_m: float, tilt: float):
    """n random ECM bases around the files' sample ECM pose (within spread_m) aiming roughly down and forward
    (each aim's components moved by up to ``tilt``): (suj, ecm arm, origins, unit aims)."""
    from surgopt.robots.models import get_model

    suj, ecm = D.CLASSIC["ECM"], get_model("dvrk_ecm_classic")
    centre = K.forward(suj, D.SAMPLE_JOINTS[("classic", "ECM")])[:3, 3]
    origins = centre + rng.uniform(-spread_m, spread_m, (n, 3))
    aims = np.array([0.0, 0.3, -1.0]) + rng.uniform(-tilt, tilt, (n, 3))
    return suj, ecm, origins, aims / np.linalg.norm(aims, axis=1)[:, None]


@pytest.mark.parametrize("solver", sorted(ECM_SOLVERS))
def test_the_classic_ecm_docks_with_its_own_yaw_and_pitch_aiming_the_scope(solver):
    """S4 on random bases around the files' sample ECM pose, aiming roughly down and forward: every docked
    solution's SUJ joints, through the reference forward kinematics, put the RCM on its origin (1e-9 m) and the
    scope's aim, in that base frame, at the returned yaw and pitch, within the ECM's ranges; its margin is the
    least of the SUJ's and the ECM's. Premises: most dock, some do not."""
    suj, ecm, origins, aims = _ecm_bases(np.random.default_rng(40), 60, 0.25, 0.6)  # the same for both solvers
    margin, joints, aim = ECM_SOLVERS[solver](suj, ecm.yaw_limits_rad, ecm.pitch_limits_rad, origins, aims)
    docked = np.flatnonzero(margin >= 0)
    assert 30 < len(docked) < 60
    for i in docked:
        base = suj_forward_reference("classic", "ECM", joints[i])
        np.testing.assert_allclose(base[:3, 3], origins[i], atol=1e-9)
        u = base[:3, :3].T @ aims[i]
        yaw, pitch = math.atan2(u[0], -u[2]), -math.asin(u[1])
        assert (yaw, pitch) == pytest.approx(tuple(aim[i]), abs=1e-9)
        want = min(yaw - ecm.yaw_limits_rad[0], ecm.yaw_limits_rad[1] - yaw, pitch - ecm.pitch_limits_rad[0],
                   ecm.pitch_limits_rad[1] - pitch,
                   *(min(K.wrap(v) - lo, hi - K.wrap(v)) if k else min(v - lo, hi - v)
                     for k, (v, (lo, hi)) in enumerate(zip(joints[i], suj.ranges))))
        assert margin[i] == pytest.approx(want, abs=1e-9)


@pytest.mark.parametrize("solver", sorted(ECM_SOLVERS))
def test_the_classic_ecm_dock_does_not_jump_with_rounding(solver):
    """S4 is a continuous function of the port and aim: the same bases solved as one batch, one at a time, and
    with each aim moved by ~1e-15, give margins within 1e-9 of each other and the same docking. (Each aim's twin
    pi - phi ties it exactly under the ECM's symmetric yaw range; an argmax that picked one of the two by
    rounding made the margin jump by up to 0.5 rad, and which ECM docks depend on the CPU and the batch size.)"""
    rng = np.random.default_rng(41)
    suj, ecm, origins, aims = _ecm_bases(rng, 80, 0.25, 0.6)
    limits = ecm.yaw_limits_rad, ecm.pitch_limits_rad
    dock = ECM_SOLVERS[solver]
    batch = dock(suj, *limits, origins, aims)[0]
    alone = np.array([dock(suj, *limits, origins[i:i + 1], aims[i:i + 1])[0][0] for i in range(80)])
    nudged = dock(suj, *limits, origins, aims * (1 + 2e-16 * rng.choice([-1, 1], (80, 1))))[0]
    finite = np.isfinite(batch)
    assert 0 < np.count_nonzero(batch >= 0) < 80  # the premise: some dock, some do not
    for other in (alone, nudged):
        assert np.array_equal(np.isfinite(other), finite) and np.array_equal(other >= 0, batch >= 0)
        np.testing.assert_allclose(other[finite], batch[finite], atol=1e-9)


def _python_margin(suj, pose) -> float:
    answer = REF.classic_psm_ik(suj, pose)
    sols = answer.within + answer.outside
    return sols[0].margin if sols else -math.inf


@pytest.mark.parametrize("arm", CLASSIC_PSMS)
def test_the_batch_solver_gives_the_closed_forms_best_margin_pose_by_pose(arm):
    """``suj_batch.classic_psm_margins`` (the jitted S2 the dock tables use) against ``classic_psm_ik`` (plain
    Python, itself held to the textbook forward kinematics above): the best solution's least margin of poses made
    from random joints (in range, and past the ranges by up to 0.5 rad), of those poses turned off what the wrist
    can tilt, and moved out of the planar chain's reach (-inf both ways). The premises: each kind occurs."""
    from surgopt.kinematics.port import suj_batch as B

    suj = D.CLASSIC[arm]
    s = B.suj_arrays(suj)
    poses = []
    for q in _random_joints(suj, 40):
        poses.append(K.forward(suj, q))
        wide = [v + RNG.uniform(-0.5, 0.5) for v in q]
        poses.append(K.forward(suj, wide))
        tilted = K.forward(suj, q)
        tilted[:3, :3] = tilted[:3, :3] @ K.mdh(RNG.uniform(-1.5, 1.5), 0.0, 0.0, 0.0)[:3, :3]
        poses.append(tilted)
        far = K.forward(suj, q)
        far[:2, 3] *= 4.0
        poses.append(far)
    poses = np.array(poses)
    got = B.classic_psm_margins(s, poses)
    want = np.array([_python_margin(suj, p) for p in poses])
    assert np.array_equal(np.isinf(got), np.isinf(want))
    np.testing.assert_allclose(got[np.isfinite(want)], want[np.isfinite(want)], rtol=0, atol=1e-12)
    assert (want >= 0).any() and ((want < 0) & np.isfinite(want)).any() and np.isinf(want).any()


def test_the_jitted_ecm_dock_picks_the_numpy_grids_point():
    """The jitted S4 walks the numpy version's grid in its order with its strict comparisons: the same margins
    (1e-12), SUJ joints (1e-9) and ECM yaw and pitch at 200 random bases, docked or not (premise: both occur)."""
    suj, ecm, origins, aims = _ecm_bases(np.random.default_rng(42), 200, 0.3, 0.8)
    limits = ecm.yaw_limits_rad, ecm.pitch_limits_rad
    want, got = REF.ecm_classic_dock(suj, *limits, origins, aims), _ecm_batch(suj, *limits, origins, aims)
    finite = np.isfinite(want[0])
    assert np.array_equal(np.isfinite(got[0]), finite) and 0 < np.count_nonzero(want[0] >= 0) < finite.sum()
    np.testing.assert_allclose(got[0][finite], want[0][finite], rtol=0, atol=1e-12)
    np.testing.assert_allclose(got[1][finite], want[1][finite], rtol=0, atol=1e-9)
    np.testing.assert_allclose(got[2][finite], want[2][finite], rtol=0, atol=1e-9)


@pytest.mark.parametrize("arm", ["PSM1", "PSM2", "PSM3"])
def test_an_si_docking_points_the_shaft_with_the_arms_own_joints(arm):
    """(S5, S6) The Si sets only its arm's yaw about the vertical; the arm's own yaw and pitch absorb the rest.
    For random aims from the sample pose's port: each docking's setup joints through the reference forward
    kinematics (typed apart, tests/reference.py) give its base, whose origin is the port; the shaft written out
    from q1, q2 in that base, (sin q1 cos q2, -sin q2, -cos q1 cos q2), is the aim; q1, q2 within the Si PSM's
    ranges; the absorbed angle is the neutral shaft's to the aim and never below the closed form's least, which
    a brute-force sweep of the yaw (3,600 steps) reaches within its step and psi* exactly; where the SUJ reaches
    the port at psi* the first docking absorbs just that (the premise: it does for some aims)."""
    from surgopt.kinematics.port import si_docking as SD
    from surgopt.robots.models import get_model
    from surgopt.studies.port_place.tables import arm_limits

    suj, limits = D.SI[arm], arm_limits(get_model("dvrk_psm_si"))
    port = K.forward(suj, D.SAMPLE_JOINTS[("si", arm)])[:3, 3]
    rng = np.random.default_rng(41)
    at_best = 0
    for _ in range(6):
        aim = rng.normal(size=3) * [0.5, 0.5, 0.3] - [0.0, 0.0, 1.0]
        aim /= np.linalg.norm(aim)
        psi, least = SD.least_absorbed(suj, aim)
        sweep = [math.acos(np.clip(K.si_orientation(suj, p) @ [0, 0, -1.0] @ aim, -1, 1))
                 for p in np.linspace(-math.pi, math.pi, 3600, endpoint=False)]
        assert least <= min(sweep) + 1e-12 and min(sweep) - least < math.radians(0.1)
        assert math.acos(np.clip(K.si_orientation(suj, psi) @ [0, 0, -1.0] @ aim, -1, 1)) == pytest.approx(least,
                                                                                                        abs=1e-9)
        answer = REF.si_docking(suj, port, aim, limits)
        assert answer.dockings and not answer.reason
        for d in answer.dockings[:20]:
            np.testing.assert_allclose(suj_forward_reference("si", arm, d.suj.joints), d.base, atol=1e-9)
            np.testing.assert_allclose(d.base[:3, 3], port, atol=1e-12)
            shaft = [math.sin(d.q1) * math.cos(d.q2), -math.sin(d.q2), -math.cos(d.q1) * math.cos(d.q2)]
            np.testing.assert_allclose(d.base[:3, :3] @ shaft, aim, atol=1e-12)
            assert limits.yaw_lo <= d.q1 <= limits.yaw_hi and limits.pitch_lo <= d.q2 <= limits.pitch_hi
            assert d.absorbed_rad == pytest.approx(math.acos(np.clip(d.base[:3, :3] @ [0, 0, -1.0] @ aim, -1, 1)),
                                                   abs=1e-9)
            assert d.absorbed_rad >= least - 1e-9 and d.suj.margin >= 0
        if REF.si_ik(suj, answer.dockings[0].base).within and abs(K.wrap(answer.dockings[0].yaw_rad - psi)) < 1e-12:
            assert answer.dockings[0].absorbed_rad == pytest.approx(least, abs=1e-9)
            at_best += 1
    assert at_best > 0


def test_an_si_docking_that_cannot_be_made_says_why():
    """A port the Si's planar chain reaches at no yaw, and an aim the arm's own pitch cannot absorb at any yaw
    where it does (the pitch's range narrowed to +-1 deg, the aim 45 deg off the family), each refused in words."""
    from surgopt.robots.models import get_model
    from surgopt.studies.port_place.tables import arm_limits

    suj, limits = D.SI["PSM1"], arm_limits(get_model("dvrk_psm_si"))
    port = K.forward(suj, D.SAMPLE_JOINTS[("si", "PSM1")])[:3, 3]
    far = REF.si_docking(suj, port + [3.0, 0.0, 0.0], np.array([0.0, 0.0, -1.0]), limits)
    assert not far.dockings and "reaches the port at no yaw" in far.reason
    narrow = limits._replace(pitch_lo=-math.radians(1.0), pitch_hi=math.radians(1.0))
    stiff = REF.si_docking(suj, port, np.array([0.0, 0.0, -1.0]), narrow)
    assert not stiff.dockings and "cannot point the shaft" in stiff.reason and "pitch" in stiff.reason


@pytest.mark.parametrize("cart", ["classic", "si"])
def test_a_views_psm_docking_is_the_rows_solver_and_agrees_with_the_plain_twin(cart):
    """Issue 53: the views dock a PSM with the rows' own solver (``carts.ClassicCart.psm_docking``: the batch S2, the
    Si's S3) and it agrees with the plain Python twin (``reference.classic_psm_ik`` / ``si_ik``), pose by pose, on
    poses the reference forward kinematics makes from random joints (some within the ranges, some outside, some
    off the Si's family): within, the same joints (1e-9), least margin (1e-12) and tightest joint; outside, the
    twin's nearest solution's joint named with its value; none, both say so. Premises: every case occurs."""
    from surgopt.studies.port_place.carts import cart_named

    rng = np.random.default_rng(11)
    the_cart, twin = cart_named(cart), (REF.classic_psm_ik if cart == "classic" else REF.si_ik)
    seen = set()
    for arm in ("PSM1", "PSM2"):
        suj = PLATFORMS[cart].suj(arm)
        n = suj.n_joints
        qs = np.column_stack([rng.uniform(-0.3, 0.9, 120), rng.uniform(-3.4, 3.4, (120, n - 1))])
        poses = np.array([suj_forward_reference(cart, arm, q) for q in qs])
        poses[::7, :3, 3] += 3.0  # far beyond the setup joints' reach
        if cart == "si":
            poses[3::7] = poses[3::7] @ K.mdh(0.2, 0, 0, 0)  # turned off the family the Si gives
        for pose in poses:
            got, want = the_cart.psm_docking(arm, pose), twin(suj, pose)
            if want.within:
                best = want.within[0]
                np.testing.assert_allclose(got.joints, best.joints, atol=1e-9)
                assert got.margin == pytest.approx(best.margin, abs=1e-12) and got.tightest == best.tightest
                seen.add("within")
            elif want.outside:
                assert not got.joints and got.margin is None
                assert got.tightest == want.outside[0].tightest and f"SUJ {got.tightest} = " in got.reason
                seen.add("outside")
            else:
                assert not got.joints and got.reason.startswith(f"{cart} {arm} SUJ: no joint values")
                seen.add("none")
    assert seen == {"within", "outside", "none"}
