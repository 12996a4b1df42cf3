"""Raven IV: kinematics against DH matrices and finite differences, the workspace estimator
against closed forms, and the sweep through the CLI."""
import math
import subprocess
import sys

import numpy as np
import pytest

import reference as R
from surgopt.kinematics import raven as K
from surgopt.studies import raven_sweep as S

AL, BE, A5 = math.radians(75), math.radians(52), 13.0  # Raven II link angles, wrist offset


@pytest.mark.parametrize("left", [True, False])
def test_fk_ik_round_trip(left):
    rng = np.random.default_rng(30 + left)
    for _ in range(300):
        q = np.array([rng.uniform(-math.pi, math.pi), math.radians(rng.uniform(20, 140)),
                      math.radians(rng.uniform(-86, 86)), rng.uniform(30, 250),
                      rng.uniform(-1.0, 1.0), math.radians(rng.uniform(-86, 86))])
        T = K.forward_kinematics(q, AL, BE, A5, left)
        q2, ok = K.inverse_kinematics(T, AL, BE, A5, left)
        assert ok
        assert np.allclose(q2, q, atol=1e-8), (q, q2)


def test_fk_matches_plain_dh_products():
    rng = np.random.default_rng(32)
    for left in (True, False):
        for _ in range(20):
            q = rng.uniform(-1, 1, 6)
            q[3] = rng.uniform(10, 200)
            z3, _ = R.raven_tool_axis(q[0], q[1], AL, BE, left)
            T = K.forward_kinematics(np.array([q[0], q[1], 0.0, q[3], q[4], q[5]]), AL, BE, A5, left)
            # the wrist sits d4 along the tool axis from the remote centre
            T4 = K.forward_kinematics(np.array([q[0], q[1], 0.0, q[3], 0.0, 0.0]), AL, BE, 0.0, left)
            assert np.allclose(T4[:3, 3], q[3] * z3, atol=1e-9)
            assert np.isfinite(T).all()


def test_ik_flags_poses_outside_the_joint_ranges():
    q = np.array([0.3, math.radians(150), 0.2, 100.0, 0.1, 0.2])  # theta2 beyond 140 deg
    _, ok = K.inverse_kinematics(K.forward_kinematics(q, AL, BE, A5, True), AL, BE, A5, True)
    assert not ok


@pytest.mark.parametrize("left", [True, False])
def test_spherical_jacobian_against_tool_axis_finite_differences(left):
    """J_s (eqs. 41-42) against d z3 / d(theta1, theta2) by finite differences.

    The printed J_s (velocity propagation in frame 3 with the paper's simplified DH:
    theta3 = 0, alpha4 = 0) is not the tool-axis Jacobian column for column, but the two
    differ only by orthogonal factors: they share their singular values, which is all
    the isotropy (eq. 35) uses."""
    rng = np.random.default_rng(33)
    h = 1e-6
    for _ in range(30):
        t1, t2 = rng.uniform(-3, 3), rng.uniform(0.2, 2.9)
        al, be = rng.uniform(0.2, 1.5), rng.uniform(0.2, 1.5)
        d1 = (R.raven_tool_axis(t1 + h, t2, al, be, left)[0] - R.raven_tool_axis(t1 - h, t2, al, be, left)[0]) / (2 * h)
        d2 = (R.raven_tool_axis(t1, t2 + h, al, be, left)[0] - R.raven_tool_axis(t1, t2 - h, al, be, left)[0]) / (2 * h)
        G_fd = np.array([[d1 @ d1, d1 @ d2], [d2 @ d1, d2 @ d2]])
        Js = K.spherical_jacobian(t2, al, be, left)[:2, :2]
        assert np.trace(Js.T @ Js) == pytest.approx(np.trace(G_fd), abs=1e-8)
        sv_fd = np.linalg.svd(np.column_stack([d1, d2]), compute_uv=False)
        assert np.allclose(np.linalg.svd(Js, compute_uv=False), sv_fd, atol=1e-8)
        assert K.isotropy_at(t2, al, be) == pytest.approx(R.isotropy_2x2(Js), rel=1e-12)
        # and the third column is the insertion: a unit vector along frame 3's z
        assert np.allclose(K.spherical_jacobian(t2, al, be, left)[:, 2], [0, 0, 1])


def test_isotropy_is_the_same_for_every_theta1():
    # Fig. 6b: J_s depends on theta2 only
    al, be = math.radians(55), math.radians(40)
    t2 = 1.1
    vals = []
    h = 1e-6
    for t1 in np.linspace(-3, 3, 7):
        d1 = (R.raven_tool_axis(t1 + h, t2, al, be)[0] - R.raven_tool_axis(t1 - h, t2, al, be)[0]) / (2 * h)
        d2 = (R.raven_tool_axis(t1, t2 + h, al, be)[0] - R.raven_tool_axis(t1, t2 - h, al, be)[0]) / (2 * h)
        s = np.linalg.svd(np.column_stack([d1, d2]), compute_uv=False)
        vals.append(s[-1] / s[0])
    assert np.allclose(vals, K.isotropy_at(t2, al, be), rtol=1e-6)


def test_isotropy_has_one_maximum_for_every_link_pair():
    t = np.radians(np.linspace(0, 180, 1441))
    for a in range(5, 91, 5):
        for b in range(5, 91, 5):
            v = np.array([K.isotropy_at(x, math.radians(a), math.radians(b)) for x in t])
            d = np.sign(np.diff(v))
            d = d[d != 0]
            assert np.sum((d[1:] < 0) & (d[:-1] > 0)) <= 1


def test_theta2_interval_fig6():
    """Fig. 6a (alpha = 55, beta = 40 deg): the theta2 range shrinks as Iso_min grows."""
    al, be = math.radians(55), math.radians(40)
    t = np.radians(np.linspace(0, 180, 180001))
    iso = np.array([K.isotropy_at(x, al, be) for x in t])
    prev = (0.0, math.pi)
    for m in (0.1, 0.3, 0.5, 0.7, 0.9):
        lo, hi, ok = K.theta2_interval(al, be, m, 0.0, math.pi)
        assert ok
        dense = t[iso >= m]
        assert lo == pytest.approx(dense.min(), abs=2e-5) and hi == pytest.approx(dense.max(), abs=2e-5)
        assert K.isotropy_at(lo, al, be) == pytest.approx(m, abs=1e-9)
        assert K.isotropy_at(hi, al, be) == pytest.approx(m, abs=1e-9)
        assert prev[0] <= lo < hi <= prev[1]
        prev = (lo, hi)
    # the numbers, for docs/reproduction.md: Iso_min 0.5 keeps theta2 in [79.6, 153.7] deg
    lo, hi, _ = K.theta2_interval(al, be, 0.5, 0.0, math.pi)
    assert math.degrees(lo) == pytest.approx(79.6, abs=0.1) and math.degrees(hi) == pytest.approx(153.7, abs=0.1)
    assert not K.theta2_interval(al, be, 0.99, 0.0, math.pi)[2]


def _field(f, step, ext):
    xs = np.arange(-ext, ext + step / 2, step)
    X, Y = np.meshgrid(xs, xs, indexing="ij")
    return f(np.hypot(X, Y)).ravel(), xs.size


@pytest.mark.parametrize("radius", [20.0, 57.3, 150.0])
def test_marching_squares_disc(radius):
    m, n = _field(lambda r: radius - r, 2.0, radius + 10)
    length, area = K.marching_squares(m, n, n, 2.0)
    assert length == pytest.approx(2 * math.pi * radius, rel=0.01)
    assert area == pytest.approx(math.pi * radius ** 2, rel=0.01)
    # the 0/1 staircase would overestimate the perimeter by 4/pi
    staircase = 2.0 * np.sum(np.abs(np.diff((m.reshape(n, n) > 0).astype(int), axis=0))) * 2
    assert staircase / (2 * math.pi * radius) > 1.2


def test_marching_squares_annulus():
    r1, r2 = 40.0, 130.0
    m, n = _field(lambda r: np.minimum(r - r1, r2 - r), 2.0, r2 + 10)
    length, area = K.marching_squares(m, n, n, 2.0)
    assert length == pytest.approx(2 * math.pi * (r1 + r2), rel=0.01)
    assert area == pytest.approx(math.pi * (r2 ** 2 - r1 ** 2), rel=0.01)
    assert area / length == pytest.approx(R.annulus_zeta_mm(r1, r2), rel=0.01)


@pytest.mark.parametrize("a_deg, b_deg", [(15, 15), (20, 40), (30, 20), (65, 80)])
def test_single_arm_workspace_is_the_closed_form_annulus(a_deg, b_deg):
    """One arm, vertical shoulder axis, theta2 over [0, 180]: tool axes fill the cone band
    |alpha - beta| .. alpha + beta around straight down, cut by d4 <= 250 mm."""
    cfg = S.Config.model_validate({"geometry": {"n_arms": 1, "shoulder_tilt_deg": 0.0,
                                                "theta2_range_deg": [0.0, 180.0]}, "sweep": {
        "alpha_deg": [a_deg], "beta_deg": [b_deg], "phi_x_deg": [0], "phi_y_deg": [0], "phi_z_deg": [0],
        "bx_mm": [0], "by_mm": [0], "iso_min": [0.0]}})
    row = S.compute_task(cfg, 1, 0)
    h = 150.0
    r_in = h * math.tan(math.radians(abs(a_deg - b_deg)))
    r_reach = math.sqrt(250.0 ** 2 - h ** 2)
    r_out = r_reach if a_deg + b_deg >= 90 else min(r_reach, h * math.tan(math.radians(a_deg + b_deg)))
    assert row["area_cm2"][0] == pytest.approx(math.pi * (r_out ** 2 - r_in ** 2) / 100, rel=0.01)
    assert row["zeta_cm"][0] == pytest.approx(R.annulus_zeta_mm(r_in, r_out) / 10, rel=0.01)


def test_fig4_two_arm_values_within_ten_percent():
    from conftest import REPO
    from surgopt.config import load_config

    cfg = load_config(REPO / "configs" / "raven_fig4.toml", S.Config)
    r = S.compute_task(cfg, 1, 0)
    z = {(a, b): v for a, b, v in zip(r["alpha_deg"], r["beta_deg"], r["zeta_cm"])}
    assert z[(15.0, 15.0)] == pytest.approx(2.23, rel=0.05)
    assert z[(65.0, 80.0)] == pytest.approx(4.48, rel=0.10)


def test_cost_formula_and_shared_geometry():
    cfg = S.Config.model_validate({"sweep": {
        "alpha_deg": [45, 85], "beta_deg": [65], "phi_x_deg": [20], "phi_y_deg": [10], "phi_z_deg": [-20],
        "bx_mm": [100], "by_mm": [50], "iso_min": [0.3, 0.5]}})
    r = S.compute_task(cfg, 1, 0)
    for i in range(4):
        a3 = math.radians(r["alpha_deg"][i]) ** 3 + math.radians(r["beta_deg"][i]) ** 3
        assert r["cost"][i] == pytest.approx(r["zeta_cm"][i] * r["iso_sum"][i] * r["iso_min"][i] / a3)
        if r["n_points"][i] == 0:
            assert r["cost"][i] == 0 and r["zeta_cm"][i] == 0
            continue
        assert r["iso_min_actual"][i] >= r["iso_min"][i] - 1e-9  # every point meets Iso_min
        assert r["iso_mean"][i] == pytest.approx(r["iso_sum"][i] / r["n_points"][i])
        # a design evaluated alone equals the same design inside a shared geometry
        alone = S.Config.model_validate({"sweep": {**{p: [r[p][i]] for p in S.PARAMS}}})
        assert S.compute_task(alone, 1, 0)["cost"][0] == r["cost"][i]
    assert (r["n_points"] > 0).sum() >= 2
    # higher Iso_min narrows theta2: the workspace can only shrink
    assert r["area_cm2"][1] <= r["area_cm2"][0] and r["area_cm2"][3] <= r["area_cm2"][2]


def test_refine_improves_on_the_grid():
    cfg = S.Config.model_validate({"sweep": {
        "alpha_deg": {"start": 25, "stop": 85, "step": 30}, "beta_deg": {"start": 25, "stop": 85, "step": 30},
        "phi_x_deg": [0], "phi_y_deg": [0], "phi_z_deg": [0], "bx_mm": [100], "by_mm": [50],
        "iso_min": [0.5]}, "geometry": {"step_mm": 4.0}, "refine": {"top_k": 1, "max_evals": 60}})
    import pyarrow as pa

    grid = pa.Table.from_pydict(S.compute_task(cfg, 1, 0), schema=S.schema())
    rcfg = S.refine_config(cfg, grid)
    rows = S.compute_task(rcfg, 1, 0)
    assert rows["cost"].max() > max(grid["cost"].to_pylist())
    assert set(rows["source"]) == {"refine"}
    for p, (lo, hi) in zip(S.PARAMS, S._bounds(cfg)):
        assert rows[p].min() >= lo - 1e-9 and rows[p].max() <= hi + 1e-9


def test_span_values_and_validation():
    assert S.Span(start=5, stop=90, step=20).values() == [5, 25, 45, 65, 85]
    assert S.Span(start=0.1, stop=0.9, step=0.2).values() == [0.1, 0.3, 0.5, 0.7, 0.9]
    cfg = S.Config()
    assert len(S.geometry_grid(cfg)) * 125 == 250_000
    from surgopt.errors import ConfigError
    from surgopt.config import validate

    with pytest.raises(ConfigError, match="sweep"):
        validate({"sweep": {"iso_min": [1.5]}}, S.Config, "x.toml")
    with pytest.raises(ConfigError, match="geometry.n_arms"):
        validate({"geometry": {"n_arms": 3}}, S.Config, "x.toml")
    ports = {"ports_mm": [[-50, 25], [50, 25], [-50, -25], [50, -25]]}
    with pytest.raises(ConfigError, match=r"x.toml: .*sweep.bx_mm .*ports_mm"):
        validate({"geometry": ports, "sweep": {"bx_mm": [50, 100]}}, S.Config, "x.toml")
    fixed = validate({"geometry": ports, "sweep": {"bx_mm": [50], "by_mm": [50]}}, S.Config, "x.toml")
    assert len(S.geometry_grid(fixed)) == 125


SMALL = """
[sweep]
alpha_deg = [45.0, 65.0]
beta_deg = [45.0, 65.0]
phi_x_deg = {start = -20.0, stop = 20.0, step = 10.0}
phi_y_deg = {start = -20.0, stop = 20.0, step = 10.0}
phi_z_deg = [0.0, 10.0]
bx_mm = [100.0]
by_mm = [50.0]
iso_min = [0.3, 0.5]
[geometry]
step_mm = 1.0
"""


def test_cli_sweep_stored_cached_and_resumed(tmp_path):
    import signal

    from conftest import wait_for_parts
    from surgopt.store import Store

    cfg = tmp_path / "small.toml"
    cfg.write_text(SMALL)
    store = tmp_path / "store"
    cmd = [sys.executable, "-m", "surgopt", "raven-sweep", str(cfg), "--store", str(store), "--quiet",
           "--jobs", "1", "--chunk-size", "1"]
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    wait_for_parts(store, "raven-sweep", 3, proc)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    (run,) = Store(store).runs()
    assert not run.complete
    r = subprocess.run(cmd[:-4], capture_output=True, text=True, check=True)
    assert "resuming" in r.stdout
    (run,) = Store(store).runs()
    resumed = run.read_table(S.schema())
    assert resumed.num_rows == 50 * 8
    fresh = S.Config.model_validate({"sweep": {"alpha_deg": [45.0, 65.0], "beta_deg": [45.0, 65.0],
                                               "phi_x_deg": {"start": -20.0, "stop": 20.0, "step": 10.0},
                                               "phi_y_deg": {"start": -20.0, "stop": 20.0, "step": 10.0},
                                               "phi_z_deg": [0.0, 10.0], "bx_mm": [100.0], "by_mm": [50.0],
                                               "iso_min": [0.3, 0.5]}, "geometry": {"step_mm": 1.0}})
    direct = S.compute_task(fresh, 1000, 0)
    assert np.array_equal(resumed["cost"].to_numpy(), direct["cost"])
    r = subprocess.run(cmd[:-4], capture_output=True, text=True, check=True)
    assert "cache hit" in r.stdout and "top designs" in r.stdout


def test_embedded_default_is_table_ii():
    from conftest import REPO
    from surgopt.config import load_config, load_embedded

    emb = load_embedded(S.DEFAULT_CONFIG, S.Config)
    assert emb == load_config(REPO / "configs" / "raven_table2.toml", S.Config)
    assert emb.sweep == S.Config().sweep and emb.geometry == S.Config().geometry


def test_cell_contour_matches_polygon_clipping():
    """The closed-form cell routine against a shoelace on the walked inside polygon (tests/reference.py)."""
    rng = np.random.default_rng(40)
    cases = rng.normal(size=(4000, 4))
    cases[:200] = np.sign(cases[:200]) * rng.uniform(1e-9, 1e-6, (200, 4))  # near-degenerate crossings
    cases[200:300] = [[1, -1, 1, -1], [-1, 1, -1, 1], [2, -1, 3, -0.5], [-2, 1, -3, 0.5]] * 25  # saddles
    for v in cases:
        length, area = K.marching_squares(np.array([v[0], v[3], v[1], v[2]]), 2, 2, 1.0)  # rows are x
        ref_len, ref_area = R.cell_contour(v)
        assert length == pytest.approx(ref_len, rel=1e-12, abs=1e-14)
        assert area == pytest.approx(ref_area, rel=1e-12, abs=1e-14)


def test_node_isotropy_is_the_minimum_over_the_arms():
    """Iso is unimodal in theta2, so the minimum over the arms sits at the lowest or highest cos psi."""
    rng = np.random.default_rng(41)
    for a_deg, b_deg in [(5, 5), (25, 85), (55, 40), (85, 85), (90, 45), (15, 75)]:
        al, be = math.radians(a_deg), math.radians(b_deg)
        lo_c, hi_c = -math.cos(al - be), -math.cos(al + be)  # theta2 = 180 and 0 deg (eq. 22)
        cos_psi = rng.uniform(lo_c, hi_c, (4, 500))  # reachable cone angles of four arms
        out = np.empty(500)
        K.node_isotropy(cos_psi.min(axis=0), cos_psi.max(axis=0), al, be, out)
        ref = R.raven_isotropy_from_cos_psi(cos_psi, al, be).min(axis=0)
        assert np.allclose(out, ref, rtol=1e-12, atol=1e-14)


def _brute_force_designs(cfg, geometry):
    """Every design of one geometry from per-arm fields: membership per arm, Iso by SVD (reference)."""
    geo = cfg.geometry
    ports, axes = S.arms(geo, *geometry)
    xs, ys = S.plane_grid(geo, ports)
    cos_psi, dist = R.raven_cone_fields(xs, ys, geo.depth_mm, ports, axes)
    lo, hi = cos_psi.min(axis=0), cos_psi.max(axis=0)
    cols = np.arange(lo.size)
    d_lo, d_hi = dist[cos_psi.argmin(axis=0), cols], dist[cos_psi.argmax(axis=0), cols]
    reach = (geo.d4_max_mm - dist).min(axis=0)
    al = [math.radians(v) for v in S.values(cfg.sweep.alpha_deg)]
    be = [math.radians(v) for v in S.values(cfg.sweep.beta_deg)]
    iso = S.values(cfg.sweep.iso_min)
    plo, phi, has = S.psi_intervals(cfg, np.array(al), np.array(be), np.array(iso))
    rows = []
    for ia, a in enumerate(al):
        for ib, b in enumerate(be):
            iso_node = R.raven_isotropy_from_cos_psi(cos_psi, a, b).min(axis=0)
            for k in range(len(iso)):
                c_lo, c_hi = math.cos(phi[ia, ib, k]), math.cos(plo[ia, ib, k])
                inside = has[ia, ib, k] & np.all((cos_psi > c_lo) & (cos_psi < c_hi) & (dist < geo.d4_max_mm), axis=0)
                margin = np.minimum(reach, np.minimum((lo - c_lo) * d_lo, (c_hi - hi) * d_hi))
                length, area = K.marching_squares(margin, xs.size, ys.size, geo.step_mm) if inside.any() else (0, 0)
                rows.append((area, length, inside.sum(), iso_node[inside].sum(), iso_node[inside].min(initial=1.0)))
    return np.array(rows)


@pytest.mark.parametrize("geometry", [(0, 10, -20, 100, 50), (10, -20, 0, 150, 100), (0, 0, 0, 50, 50)])
def test_designs_of_a_geometry_equal_a_brute_force_evaluation(geometry):
    """The level-sharing kernel against per-design, per-arm membership and SVD isotropy."""
    cfg = S.Config.model_validate({"geometry": {"step_mm": 4.0}, "sweep": {
        "alpha_deg": [25, 65, 85], "beta_deg": [45, 85], "phi_x_deg": [geometry[0]], "phi_y_deg": [geometry[1]],
        "phi_z_deg": [geometry[2]], "bx_mm": [geometry[3]], "by_mm": [geometry[4]], "iso_min": [0.1, 0.5, 0.3, 0.9]}})
    got = S.compute_task(cfg, 1, 0)
    ref = _brute_force_designs(cfg, geometry)
    assert np.array_equal(got["n_points"], ref[:, 2])
    assert (ref[:, 2] > 0).sum() >= 6  # non-trivial
    assert np.allclose(got["iso_sum"], ref[:, 3], rtol=1e-11, atol=1e-12)
    nonempty = ref[:, 2] > 0
    assert np.allclose(got["iso_min_actual"][nonempty], ref[nonempty, 4], rtol=1e-11)
    assert np.allclose(got["area_cm2"] * 100, ref[:, 0], rtol=1e-11, atol=1e-9)
    assert np.allclose(got["perimeter_cm"] * 10, ref[:, 1], rtol=1e-11, atol=1e-9)


def test_plane_grid_covers_every_reachable_node():
    geo = S.Config().geometry
    for g in [(0, 0, 0, 50, 50), (20, -10, 10, 200, 150), (0, 0, 0, 200, 200)]:
        ports, _ = S.arms(geo, *g)
        xs, ys = S.plane_grid(geo, ports)
        reach = math.sqrt(geo.d4_max_mm ** 2 - geo.depth_mm ** 2)
        X, Y = np.meshgrid(np.arange(-400, 400.1, 2.0), np.arange(-400, 400.1, 2.0), indexing="ij")
        ok = np.all([(X - p[0]) ** 2 + (Y - p[1]) ** 2 <= reach ** 2 for p in ports], axis=0)
        if ok.any():
            assert xs.min() < X[ok].min() and xs.max() > X[ok].max()
            assert ys.min() < Y[ok].min() and ys.max() > Y[ok].max()
            assert np.allclose(np.diff(xs), geo.step_mm) and np.allclose(np.diff(ys), geo.step_mm)


def test_identical_geometries_share_one_evaluation():
    """Horizontal shoulder axes along x: phi_x turns them about themselves, so its rows coincide;
    the memo hands them over, and memo hits equal fresh evaluations."""
    cfg = S.Config.model_validate({"geometry": {"step_mm": 4.0}, "sweep": {
        "alpha_deg": [45, 85], "beta_deg": [65], "phi_x_deg": [-20, 0, 20], "phi_y_deg": [10], "phi_z_deg": [-20],
        "bx_mm": [100], "by_mm": [50], "iso_min": [0.3, 0.7]}})
    S._MEMO.clear()
    a = S.compute_task(cfg, 3, 0)
    per = 4
    for c in ("area_cm2", "perimeter_cm", "iso_sum", "n_points", "cost"):
        v = np.asarray(a[c]).reshape(3, per)
        assert np.array_equal(v[0], v[1]) and np.array_equal(v[0], v[2])
    b = S.compute_task(cfg, 3, 0)  # all from the memo now
    S._MEMO.clear()
    c = S.compute_task(cfg, 1, 2)  # the last geometry alone, computed afresh
    for k in ("area_cm2", "perimeter_cm", "iso_sum", "cost"):
        assert np.array_equal(a[k], b[k])
        assert np.array_equal(np.asarray(a[k])[2 * per:], c[k])
