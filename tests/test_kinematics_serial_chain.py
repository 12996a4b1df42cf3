"""The generic serial-chain RCM kernel (surgopt/kinematics/serial_chain.py).

Checked against: the closed-form PA10 kernel (the same arm from its DH table and from a URDF file written
independently in tests/data), textbook DH products in tests/reference.py, finite differences, and the
five equations themselves recomputed in numpy.
"""
import math
from pathlib import Path

import numpy as np
import pytest

import reference as ref
from surgopt.config import load_embedded, validate
from surgopt.kinematics import chain_candidates as cc
from surgopt.kinematics import serial_chain as sc
from surgopt.robots import pa10_7c
from surgopt.robots.chain import chain_transform
from surgopt.robots.models import MODELS, get_model
from surgopt.studies.rcm_grid import study as S

DATA = Path(__file__).parent / "data"
D1 = pa10_7c.LINKS_BIELEFELD_M[0]


def pa10_configs():
    """The paper setup three ways: closed form, generic from the DH table, generic from the URDF file."""
    closed = load_embedded(S.DEFAULT_CONFIG, S.Config)
    dh = validate({"robot": {"kernel": "generic"}}, S.Config, "test")
    urdf = validate({"robot": {"urdf": str(DATA / "pa10_7c.urdf"), "tool_length_m": pa10_7c.TOOL_LENGTH_M,
                               "locked_joints_deg": {"S3": 0.0, "W2": 0.0}, "seed_deg": pa10_7c.SEED_DEG}},
                    S.Config, "test")
    return closed, dh, urdf


def rows_for(cfg, xz_shoulder):
    """Rows of the study for candidates given as (x, z from the shoulder)."""
    xz = np.asarray(xz_shoulder, float)
    if cfg.candidates.z_reference == "shoulder":
        lst = [[x, z] for x, z in xz]
    else:
        lst = [[x, 0.0, z + D1] for x, z in xz]
    c = cfg.model_copy(update={"candidates": S.Candidates(z_reference=cfg.candidates.z_reference, list_m=lst)})
    return S.compute_task(c, len(lst), 0)


def test_serpentine_order_steps_one_cell_at_a_time():
    assert sc.serpentine_order(2).tolist() == [0, 1, 3, 2, 6, 7, 5, 4]
    n = 5
    order = sc.serpentine_order(n)
    assert sorted(order.tolist()) == list(range(n ** 3))
    ijk = np.stack(np.unravel_index(order, (n, n, n)), axis=1)
    assert (np.abs(np.diff(ijk, axis=0)).sum(axis=1) == 1).all()


@pytest.mark.parametrize("which", ["dh", "urdf"])
def test_pa10_through_the_generic_kernel_gives_the_closed_form_results(which):
    """Table I's 15 rows and a 21 x 21 map: the same feasible set and GII within 1e-9 relative."""
    closed, dh, urdf = pa10_configs()
    generic = dh if which == "dh" else urdf
    xs, zs = np.linspace(0.2, 0.8, 21), np.linspace(-0.6, 0.0, 21)
    grid = [[x, z] for x in xs for z in zs]
    for cands in ([r[:2] for r in S.PAPER_TABLE_I], grid):
        a, b = rows_for(closed, cands), rows_for(generic, cands)
        assert (a["feasible"] == b["feasible"]).all()
        f = a["feasible"]
        assert f.sum() > 0.3 * f.size
        np.testing.assert_allclose(b["gii"][f], a["gii"][f], rtol=1e-9, atol=0)
        np.testing.assert_allclose(b["sigma_max_m_per_s"][f], a["sigma_max_m_per_s"][f], rtol=1e-9)
        assert (b["gii"][~f] == 0).all()


def test_ik_solutions_satisfy_the_five_equations_and_stay_on_the_seeded_branch():
    """Every point of the walk, recomputed with textbook DH matrices: tip on the target and the RCM on the
    tool line to 1e-10 m; and every solution on the closed form's branch."""
    _, dh, _ = pa10_configs()
    chain, names, seed = dh.robot.chain()
    offsets = S.workspace_offsets(dh.workspace)[sc.serpentine_order(17)]
    rcm = np.array([0.535, 0.0, -0.210 + D1])
    r = sc.rcm_walk(chain, rcm, offsets, seed)
    assert r["n_unreachable"] == 0 and r["points_evaluated"] == offsets.shape[0]
    q = r["q"]
    model = get_model("pa10_7c")
    worst_tip = worst_line = 0.0
    for qa, off in zip(q[::7], offsets[::7]):
        q7 = np.zeros(7)
        q7[[0, 1, 3, 4, 5]] = qa
        tip, line = ref.tool_line_rcm_error(ref.dh_chain_transform(model, q7), pa10_7c.TOOL_LENGTH_M, rcm + off, rcm)
        worst_tip, worst_line = max(worst_tip, tip), max(worst_line, line)
    assert worst_tip < 1e-10 and worst_line < 1e-10
    # one branch all the way: at every point the joints equal the closed-form IK's elbow-up, W1 >= 0
    # solution (tests/reference.py, angles by atan2/acos)
    for qa, off in zip(q, offsets):
        p = rcm + off
        want = ref.pa10_ik(p, (p - rcm) / np.linalg.norm(p - rcm), pa10_7c.LINKS_BIELEFELD_M, pa10_7c.TOOL_LENGTH_M)
        assert np.abs(np.angle(np.exp(1j * (qa - want)))).max() < 1e-7


@pytest.mark.parametrize("name", sorted(MODELS))
def test_jacobian_against_finite_differences(name):
    """The 5 x 5 Jacobian of the five equations at an IK solution (where the constraint rows are the RCM
    body point's velocity) against central differences of the residual."""
    cfg = validate({"robot": {"model": name, "kernel": "generic"} if name == "pa10_7c" else {"model": name}},
                   S.Config, "test")
    chain, names, seed = cfg.robot.chain()
    g = cfg.candidates.grid
    xyz = S.candidate_xyz(cfg)
    offsets = S.workspace_offsets(cfg.workspace.model_copy(update={"points_per_side": 3}))
    walk = offsets[sc.serpentine_order(3)]
    rcms = S.candidate_rcms(cfg, xyz)
    found = 0
    for rcm in rcms[:: max(1, len(rcms) // 40)]:
        r = sc.rcm_walk(chain, rcm, walk, seed)
        if r["n_unreachable"]:
            continue
        for q, off in zip(r["q"][::9], walk[::9]):
            res, jac = sc.rcm_jacobian(chain, q, rcm + off, rcm)
            assert np.abs(res).max() < 1e-10
            fd = ref.finite_difference_jacobian(lambda v: sc.rcm_jacobian(chain, v, rcm + off, rcm)[0], q)
            np.testing.assert_allclose(jac, fd, atol=1e-7)
            found += 1
        if found >= 6:
            break
    assert found >= 6, f"{name}: too few feasible candidates on its default grid {g}"


@pytest.mark.parametrize("name", sorted(MODELS))
def test_chain_fk_matches_textbook_dh_products(name):
    """ChainSpec FK and the kernel's FK of the reduced chain (locked joints at their values, tool appended)
    against 4x4 DH matrices multiplied out in tests/reference.py."""
    model = get_model(name)
    cfg = validate({"robot": {"model": name, "kernel": "generic"}}, S.Config, "test")
    spec = cfg.robot.chain_spec()
    chain, names, _ = cfg.robot.chain()
    rng = np.random.default_rng(7)
    for _ in range(5):
        q = rng.uniform(-2.5, 2.5, len(model.dh))
        for n, v in cfg.robot.locked_joints_deg.items():
            q[model.joint_names.index(n)] = math.radians(v)
        want = ref.dh_chain_transform(model, q)
        np.testing.assert_allclose(chain_transform(spec, q), want, atol=1e-12)
        active = [model.joint_names.index(n) for n in names]
        tool, axes, origins = sc.chain_fk(chain, q[active])
        flange_tip = want[:3, 3] + cfg.robot.tool_length_m * want[:3, 2]
        if name == "pa10_7c" and cfg.robot.tool_length_from == "wrist_centre":
            flange_tip -= cfg.robot.link_d7_m * want[:3, 2]
        np.testing.assert_allclose(tool[:3, 3], flange_tip, atol=1e-12)
        np.testing.assert_allclose(tool[:3, 2], want[:3, 2], atol=1e-12)
        # joint axes through the joint origins: the reference frames' z axes (DH: frame i-1 for joint i)
        frames = [np.eye(4)]
        f = ref.dh_standard if model.convention == "standard" else ref.dh_modified
        for row, v in zip(model.dh, q):
            frames.append(frames[-1] @ f(v, row.d_m, row.a_m, row.alpha_rad))
        for k, n in enumerate(names):
            i = model.joint_names.index(n)
            fr = frames[i] if model.convention == "standard" else frames[i + 1]
            np.testing.assert_allclose(axes[k], fr[:3, 2], atol=1e-12)
            # the kernel's origin lies on the joint's axis line
            d = origins[k] - fr[:3, 3]
            assert np.linalg.norm(d - (d @ fr[:3, 2]) * fr[:3, 2]) < 1e-12


def test_iiwa_standard_and_modified_tables_agree():
    """The two public forms of the LBR iiwa 14 table (standard alphas in the model file, the modified
    alpha_{i-1} quoted there) give the same flange pose."""
    from surgopt.robots import lbr_iiwa_14 as m

    model = get_model("lbr_iiwa_14")
    q = np.random.default_rng(3).uniform(-2, 2, 7)
    t_std = ref.dh_chain_transform(model, q)
    t = np.eye(4)
    for row, alpha, v in zip(model.dh, m.MODIFIED_ALPHA_DEG, q):
        t = t @ ref.dh_modified(v, row.d_m, 0.0, math.radians(alpha))
    np.testing.assert_allclose(t[:3, 3], t_std[:3, 3], atol=1e-12)
    np.testing.assert_allclose(t[:3, 2], t_std[:3, 2], atol=1e-12)


def test_urdf_chain_matches_yourdfpy_transforms():
    """Our reading of the URDF (fixed joints folded, axes along y and z) against yourdfpy's own forward
    kinematics of the same file, and against the PA10's DH table."""
    import yourdfpy

    from surgopt.robots.chain import from_dh, from_urdf

    u = yourdfpy.URDF.load(str(DATA / "pa10_7c.urdf"), load_meshes=False, build_scene_graph=True)
    spec = from_urdf(DATA / "pa10_7c.urdf", None, None)
    assert spec.names == pa10_7c.JOINT_NAMES
    dh = from_dh(pa10_7c.dh_rows())
    rng = np.random.default_rng(11)
    for _ in range(5):
        q = rng.uniform(-1.5, 1.5, 7)
        u.update_cfg(q)
        np.testing.assert_allclose(chain_transform(spec, q), u.get_transform("flange", "world"), atol=1e-12)
        np.testing.assert_allclose(chain_transform(dh, q), u.get_transform("flange", "world"), atol=1e-12)


def test_unreachable_candidate_and_joint_limits():
    """A candidate out of reach is infeasible (sigma 0, one unreachable point); narrowing a joint range
    below what the walk needs makes a feasible candidate infeasible."""
    _, dh, _ = pa10_configs()
    chain, names, seed = dh.robot.chain()
    offsets = S.workspace_offsets(dh.workspace.model_copy(update={"points_per_side": 5}))[sc.serpentine_order(5)]
    lo, hi, n_unr, n_sing, n_eval = cc.chain_candidates_extremes(
        np.array([[3.0, 0.0, 0.3], [0.535, 0.0, 0.107]]), offsets, chain, seed)
    assert n_unr.tolist() == [1, 0] and lo[0] == 0 and hi[0] == 0 and n_eval[1] == 125
    r = sc.rcm_walk(chain, [0.535, 0.0, 0.107], offsets, seed)
    w1 = r["q"][:, 4]
    tight = chain._replace(upper=chain.upper.copy())
    tight.upper[4] = 0.5 * (w1.min() + w1.max())
    assert sc.rcm_walk(tight, [0.535, 0.0, 0.107], offsets, seed)["n_unreachable"] == 1


def test_culling_bound_stops_the_walk():
    """With gii_to_beat above a candidate's GII the walk stops early with a bound >= the true GII."""
    _, dh, _ = pa10_configs()
    chain, _, seed = dh.robot.chain()
    offsets = S.workspace_offsets(dh.workspace.model_copy(update={"points_per_side": 9}))[sc.serpentine_order(9)]
    rcm = np.array([[0.535, 0.0, 0.107]])
    lo, hi, _, _, n_eval = cc.chain_candidates_extremes(rcm, offsets, chain, seed)
    gii = lo[0] / hi[0]
    lo2, hi2, _, _, n_eval2 = cc.chain_candidates_extremes(rcm, offsets, chain, seed, gii_to_beat=[2 * gii])
    assert n_eval2[0] < n_eval[0] and lo2[0] / hi2[0] >= gii
