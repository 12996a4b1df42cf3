"""Issue 54 item 1: the endoscope as the ECM can hold it. Over every row of a small run, the scope's tip is written
out here from the port, the target's centre and the ECM's own numbers (dvrk-kinematics.md: insertion 0 ... 0.255 m,
the tip 0.0007 m past q3; the controller's 50 mm least insertion), independent of ``camera_views``: the rows' tip
depth and standoff are those, the tip lies inside the body, and the camera's coverage is seen from there."""
import math

import numpy as np
import pytest

from surgopt.studies.port_place import config as C
from surgopt.studies.port_place import geometry as G
from surgopt.studies.port_place import study as S

SMALL = {"patient": {"port_region": {"site_spacing_mm": 36.0}}, "target": {"spacing_mm": 15.0}, "cart": {"model": "none"}}
TIP_PAST_Q3_M = -0.3822 + 0.3829  # ECM.json: the insertion row's offset plus the roll row's D
LEAST_INSERTION_M, MOST_INSERTION_M = 0.050, 0.255


def _inside_half_ellipsoid(p_mm: np.ndarray, semi_axes_mm) -> np.ndarray:
    a, b, h = semi_axes_mm
    return ((p_mm[:, 0] / a) ** 2 + (p_mm[:, 1] / b) ** 2 + (p_mm[:, 2] / h) ** 2 < 1.0) & (p_mm[:, 2] > 0)


@pytest.fixture(scope="module")
def rows():
    cfg = C.PortPlaceConfig.model_validate(SMALL)
    return cfg, S.compute_task(cfg, S.n_total(cfg), 0)


def test_every_rows_scope_is_inserted_within_the_ecms_range_and_its_tip_is_inside_the_body(rows):
    cfg, cols = rows
    assert cfg.patient.shape == "dome" and cfg.patient.dome_exponent == 2.0  # the premise: an ellipsoid's half
    centre = np.asarray(cfg.target.centre_mm, float)
    port = np.column_stack([cols[f"ecm_{c}_mm"] for c in "xyz"])
    dist = np.linalg.norm(centre - port, axis=1)
    placed = np.isfinite(cols["ecm_tip_depth_mm"])
    assert cols["feasible"].any() and not (cols["feasible"] & ~placed).any()
    depth = np.maximum(dist - cfg.robot.camera_standoff_mm, (LEAST_INSERTION_M + TIP_PAST_Q3_M) * 1000)
    np.testing.assert_allclose(cols["ecm_tip_depth_mm"][placed], depth[placed], atol=1e-9)
    np.testing.assert_allclose(cols["ecm_tip_to_target_mm"][placed], (dist - depth)[placed], atol=1e-9)
    q3 = depth / 1000 - TIP_PAST_Q3_M
    assert (q3[placed] >= LEAST_INSERTION_M - 1e-12).all() and (q3[placed] <= MOST_INSERTION_M).all()
    clamped = placed & (dist - cfg.robot.camera_standoff_mm < depth - 1e-9)
    assert clamped.any() and (placed & ~clamped).any()  # the premise: both kinds of port occur
    tips = port + (centre - port) / dist[:, None] * depth[:, None]
    assert _inside_half_ellipsoid(tips[placed], cfg.patient.semi_axes_mm).all()


def test_the_cameras_coverage_is_seen_from_the_tip_where_it_is(rows):
    cfg, cols = rows
    centre = np.asarray(cfg.target.centre_mm, float)
    points = G.target_points_mm(cfg.target)
    half = math.radians(cfg.robot.camera_fov_deg) / 2
    near, far = cfg.robot.camera_range_mm
    for ecm_site in np.unique(cols["ecm_site"])[::3]:
        r = int(np.flatnonzero(cols["ecm_site"] == ecm_site)[0])
        port = np.array([cols[f"ecm_{c}_mm"][r] for c in "xyz"])
        if not np.isfinite(cols["ecm_tip_depth_mm"][r]):
            assert cols["camera_coverage"][r] == 0.0
            continue
        u = (centre - port) / np.linalg.norm(centre - port)
        tip = port + cols["ecm_tip_depth_mm"][r] * u
        v = points - tip
        d = np.linalg.norm(v, axis=1)
        seen = (d >= near) & (d <= far) & (v @ u >= d * math.cos(half))
        assert cols["camera_coverage"][r] == pytest.approx(seen.mean(), abs=1e-12)


def test_the_least_insertion_is_the_configs_and_a_scope_that_cannot_reach_it_is_refused():
    from pydantic import ValidationError

    cfg = C.PortPlaceConfig.model_validate({**SMALL, "robot": {"camera_min_insertion_mm": 20.0}})
    cols = S.compute_task(cfg, S.n_total(cfg), 0)
    placed = np.isfinite(cols["ecm_tip_depth_mm"])
    assert cols["ecm_tip_depth_mm"][placed].min() == pytest.approx(20.0 + TIP_PAST_Q3_M * 1000, abs=1e-9)
    with pytest.raises(ValidationError, match="camera_min_insertion_mm: 300 mm, but dvrk_ecm_classic's insertion ends"):
        C.PortPlaceConfig.model_validate({"robot": {"camera_min_insertion_mm": 300.0}})
