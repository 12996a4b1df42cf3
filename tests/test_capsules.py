"""The arms' links outside the body as capsules (issue 40): capsule clearances against closed forms and a
brute-force sampling of the capsules' surfaces, the slab distance against sampling, the PSM skeleton of the
dVRK's robot description against the DH model typed apart in tests/reference.py, and a layout whose setup
joints must cross refused with the pair named."""
import math

import numpy as np
import pytest

from surgopt.kinematics.port import capsules as C
from surgopt.robots.dvrk import links as L
from surgopt.studies.port_place import clashes as X
from surgopt.studies.port_place import config as CF
from surgopt.studies.port_place import tables as T
from surgopt.studies.port_place import model as M

from reference import PSM_CLASSIC_MDH, mdh_chain, segment_distance_sampled

SMALL = {"patient": {"port_region": {"site_spacing_mm": 36.0}}, "target": {"spacing_mm": 15.0}, "cart": {"model": "none"}}


def _sphere_directions(n=12):
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, n, endpoint=False), np.linspace(-np.pi / 2, np.pi / 2, n // 2 + 1))
    return np.stack([np.cos(v) * np.cos(u), np.cos(v) * np.sin(u), np.sin(v)], axis=-1).reshape(-1, 3)


def _surface_samples(p0, p1, r, n_along=41):
    """Points on the spheres swept along the capsule's segment (its surface is among them): an outer sampling,
    30 degrees between directions."""
    t = np.linspace(0.0, 1.0, n_along)[:, None, None]
    return (p0 + t * (p1 - p0) + r * _sphere_directions()[None]).reshape(-1, 3)


def _least_distance(a, b):
    """The least distance between two point sets, |a|^2 + |b|^2 - 2 a.b in one matrix."""
    d2 = (a * a).sum(1)[:, None] + (b * b).sum(1)[None] - 2 * a @ b.T
    return float(np.sqrt(max(d2.min(), 0.0)))


def test_capsule_clearance_matches_closed_forms():
    """Parallel segments side by side: their distance less the radii; crossing skew segments: the common
    normal's length; end to end on one line: the gap; overlapping: negative by the overlap."""
    seg = lambda *p: np.array(p, float).reshape(1, 2, 3)
    r = np.array([0.05])
    cases = [(seg((0, 0, 0), (1, 0, 0)), seg((0, 0.3, 0), (1, 0.3, 0)), 0.3 - 0.1),
             (seg((-1, 0, 0), (1, 0, 0)), seg((0, -1, 0.25), (0, 1, 0.25)), 0.25 - 0.1),
             (seg((0, 0, 0), (1, 0, 0)), seg((1.4, 0, 0), (2, 0, 0)), 0.4 - 0.1),
             (seg((0, 0, 0), (1, 0, 0)), seg((0.5, 0.06, -1), (0.5, 0.06, 1)), 0.06 - 0.1)]
    for a, b, want in cases:
        c, i, j = C.least_pair_clearance(a, r, b, r)
        assert c == pytest.approx(want, abs=1e-12) and (i, j) == (0, 0)


def test_least_clearance_over_poses_matches_sampled_capsule_surfaces():
    """Random arms of 3 links at 3 poses each: the least clearance over every pair of poses and links against
    the segments' distances by sampling (tests/reference.py) less the radii, over all 81 pairs; and the pair it
    names against points sampled on the two capsules' surfaces (an upper bound closing on it: within 5 mm at
    this sampling), for capsules that do not overlap."""
    rng = np.random.default_rng(40)
    checked = 0
    for _ in range(6):
        a = rng.uniform(-0.4, 0.4, (3, 3, 2, 3))
        b = rng.uniform(-0.4, 0.4, (3, 3, 2, 3)) + [0.9, 0.0, 0.0]
        ra, rb = rng.uniform(0.01, 0.04, 3), rng.uniform(0.01, 0.04, 3)
        c, pa, pb, i, j = C.least_over_poses(a, ra, b, rb)
        sampled = min(segment_distance_sampled(*a[p, k], *b[s, l]) - ra[k] - rb[l]
                      for p in range(3) for s in range(3) for k in range(3) for l in range(3))
        assert c <= sampled + 1e-12 and sampled - c < 3e-3
        if c <= 0.0:
            continue
        surface = _least_distance(_surface_samples(*a[pa, i], ra[i]), _surface_samples(*b[pb, j], rb[j]))
        assert c <= surface + 1e-12 and surface - c < 5e-3
        checked += 1
    assert checked >= 3  # the premise: clear pairs were compared on their surfaces


def test_segment_to_slab_distance_matches_sampling():
    """Golden-section search along a segment for its distance to a box against 20,001 samples; a segment
    above the box reads its height; one through it, 0."""
    rng = np.random.default_rng(7)
    lo, hi = np.array([-0.3, -1.0, -0.1]), np.array([0.3, 1.0, 0.0])
    for _ in range(20):
        p0, p1 = rng.uniform(-1.5, 1.5, 3), rng.uniform(-1.5, 1.5, 3)
        d, t = C.segment_box_distance(p0, p1, lo, hi)
        s = np.linspace(0, 1, 20001)[:, None]
        want = C.box_distance(p0 + s * (p1 - p0), lo, hi).min()
        assert d == pytest.approx(want, abs=1e-7)
        assert C.box_distance(p0 + t * (p1 - p0), lo, hi) == pytest.approx(d, abs=1e-12)
    assert C.segment_box_distance(np.array([-1, 0, 0.2]), np.array([1, 0, 0.2]), lo, hi)[0] == pytest.approx(0.2)
    assert C.segment_box_distance(np.array([0, 0, -1.0]), np.array([0, 0, 1.0]), lo, hi)[0] == 0.0


@pytest.mark.parametrize("q", [(0.0, 0.0, 0.0), (0.7, -0.4, 0.12), (-1.2, 0.8, 0.24), (0.3, 0.2, 0.05)])
def test_psm_skeleton_agrees_with_the_dh_model(q):
    """The Classic PSM's skeleton (the dVRK's URDF description) at (yaw, pitch, insertion): the carriage lies on
    the DH model's shaft line behind the RCM, 0.4318 - q3 from it, and 0.4162 m along the carriage's z is the
    DH model's wrist (the roll joint's frame: tests/reference.py's modified-DH chain); the parallelogram's
    pivots stay on the yaw axis (the base's -y) whatever the pitch."""
    f = C.skeleton(L.PSM_CLASSIC_FRAMES, np.array(q), np.eye(4))
    wrist = mdh_chain(PSM_CLASSIC_MDH, q)[:3, 3]
    carriage = f["carriage"]
    np.testing.assert_allclose(carriage[:3, :3] @ [0, 0, 0.4162] + carriage[:3, 3], wrist, atol=1e-12)
    shaft = mdh_chain(PSM_CLASSIC_MDH[:3], q)[:3, 2]  # the insertion joint's axis: the shaft, into the body
    np.testing.assert_allclose(carriage[:3, 3], -(0.4318 - q[2]) * shaft, atol=1e-12)
    for pivot, along_yaw_m in (("back", 0.5185), ("front", 0.4285)):
        p = f[pivot][:3, 3]
        assert -p[1] == pytest.approx(along_yaw_m, abs=1e-12) and math.hypot(p[0], p[2]) == pytest.approx(0.0295)


@pytest.mark.parametrize("q", [(0.0, 0.0, 0.0), (0.7, -0.4, 0.12), (-1.2, 0.8, 0.24), (0.3, 0.2, 0.05)])
def test_the_si_psm_skeleton_agrees_with_the_dh_model_and_the_si_setup_joints(q):
    """The Si PSM's skeleton (the dVRK's Si URDF, its pitch zero SI_PITCH_OFFSET_RAD off PSM_Si.json's) at (yaw,
    pitch, insertion): the carriage's insertion axis is the DH model's shaft (tests/reference.py's modified-DH
    chain, the Si's offsets) to 2e-5, the carriage on that line within 4 mm of the RCM, 0.4826 - q3 behind it
    (4 mm); and the arm's base, where the URDF puts it, is the Si setup joints' last frame at the files' sample
    joints within 1 cm (two descriptions of one arm: the URDF's 0.843 m from the RCM, suj-si-simulated.json's
    tip transform 0.834 m)."""
    from surgopt.kinematics.port import suj as S
    from surgopt.robots.dvrk.suj import SAMPLE_JOINTS
    from surgopt.robots.dvrk.platforms import PLATFORMS

    si = [(math.pi / 2, 0.0, 0.0, False, math.pi / 2), (-math.pi / 2, 0.0, 0.0, False, -math.pi / 2),
          (math.pi / 2, 0.0, 0.0, True, -0.4826)]  # PSM_Si.json's yaw, pitch, insertion (dvrk-kinematics.md)
    f = C.skeleton(L.PSM_SI_FRAMES, np.array(q), np.eye(4))
    carriage = f["carriage"]
    shaft = mdh_chain(si, q)[:3, 2]  # the insertion joint's axis: the shaft, into the body
    np.testing.assert_allclose(carriage[:3, 2], shaft, atol=2e-5)
    np.testing.assert_allclose(carriage[:3, 3], -(0.4826 - q[2]) * shaft, atol=4e-3)
    for arm in ("PSM1", "PSM2", "PSM3"):
        frames = S.frames(PLATFORMS["si"].suj(arm), SAMPLE_JOINTS[("si", arm)])
        docked = C.skeleton(L.PSM_SI_FRAMES, np.zeros(3), frames[-1], frames[-2])
        assert np.linalg.norm(docked["arm base"][:3, 3] - docked["mount"][:3, 3]) < 0.01


def test_crossed_setup_joints_are_refused_with_the_pair_named():
    """The cart at the patient's feet on the midline; two mirror-image ports where both PSM1's and PSM2's setup
    joints dock: on the straight assignment (each arm to the port on its own side) the two arms' links clear
    each other further than when crossed (each reaching over to the other side), where the setup joints'
    links overlap (negative clearance) and the report names a link of each arm. The premise: both assignments
    dock."""
    # mounts below the table top allowed (#54 refuses them by default): from the feet, the mirror-image lateral
    # ports both PSMs dock at hold their mounts low; this test is about the arms crossing
    cfg = CF.PortPlaceConfig.model_validate(
        {**SMALL, "cart": {"model": "classic", "pose": "given", "x_mm": 0.0, "y_mm": -1500.0, "heading_deg": 0.0,
                           "mount_below_table_top": "allow"}})
    model = M.model_of(cfg)
    sites = model.sites_m * 1000
    ok = model.dock.margin[:, :, 0] >= 0
    pairs = [(i, int(np.flatnonzero(np.all(np.isclose(sites, s * [-1, 1, 1]), axis=1))[0]))
             for i, s in enumerate(sites) if s[0] < -100]
    both = [(i, j) for i, j in pairs if ok[0, i] and ok[1, i] and ok[0, j] and ok[1, j]]
    assert both  # the premise
    i, j = both[0]

    def clearance(p1, p2):
        row = {"cart_x_mm": 0.0, "cart_y_mm": -1500.0, "cart_heading_deg": 0.0,
               "psm1_site": p1, "psm2_site": p2, "ecm_site": -1}
        for arm, s in (("psm1", p1), ("psm2", p2)):
            row.update({f"{arm}_{c}_mm": sites[s, k] for k, c in enumerate("xyz")})
        docked = T.docked_arms(M.model_of(cfg), {k: v for k, v in row.items() if not k.startswith("ecm")})
        assert all(a.joints for a in docked)
        found = next(c for c in X.layout_clearances(M.model_of(cfg), row, docked) if c.check == "PSM1 and PSM2, docked")
        # the setup joints' links alone (the arms' own, their meshes' capsules, may meet either way round)
        patient = T.row_patient_in_cart(cfg, row)
        model = M.model_of(cfg)
        arms = [X.arm_poses(model, a, patient, model.targets_m[:0]) for a in docked]
        keep = [np.array(["setup joint link" in n for n in a.names]) for a in arms]
        value, i, j = C.least_pair_clearance(arms[0].segments[0][keep[0]], arms[0].radii[keep[0]],
                                           arms[1].segments[0][keep[1]], arms[1].radii[keep[1]])
        names = [np.array(a.names)[k] for a, k in zip(arms, keep)]
        return found, X.Clearance("PSM1 and PSM2 setup joints, docked", value * 1000, names[0][i], names[1][j],
                                  "docked")

    left, right = (i, j) if sites[i, 0] < 0 else (j, i)
    (whole_a, a), (whole_b, b) = clearance(left, right), clearance(right, left)
    crossed, straight = (a, b) if a.clearance_mm < b.clearance_mm else (b, a)
    assert crossed.clearance_mm < 0 and straight.clearance_mm > crossed.clearance_mm
    assert crossed.link_a.startswith("PSM1 ") and crossed.link_b.startswith("PSM2 ")
    for whole in (whole_a, whole_b):  # the layout's least over every link is no more than its setup joints'
        assert whole.link_a.startswith("PSM1 ") and whole.link_b.startswith("PSM2 ") and whole.clearance_mm < 0
    assert min(whole_a.clearance_mm, whole_b.clearance_mm) <= crossed.clearance_mm + 1e-9
