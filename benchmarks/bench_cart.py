"""port-place with the patient cart (issue 40): the setup joints' solvers and the (layout, cart pose) pairs end to end.

Run:  python benchmarks/bench_cart.py
Prints, on the default config with the Classic cart on its grid of floor poses (164 sites, 150 poses):
- the Classic PSM SUJ's closed form (S2): the jitted batch (``kinematics.port.suj_batch.classic_psm_margins``) in solves/s
  against the plain Python ``tests/reference.classic_psm_ik`` pose by pose (a sample), the two checked equal;
- the Classic ECM's docking grid (S4): the jitted ``ecm_margins`` against the numpy ``ecm_classic_dock`` vectorised
  over the sites (one cart pose at a time), checked equal;
- `surgopt port-place cart.model=classic` end to end, warm, 2 threads: the (layout, cart pose) pairs it decides
  (every layout against every pose of the grid, 64 poses a word in the design kernel), pairs/s, and the estimate
  the dry run printed beforehand against the time taken, docking alone (``constraints.min_link_clearance_mm=off``),
  also with a finer grid of 300+ poses; and with the links deciding (the default: every arm's links clear of each
  other, the patient and the table), its time against the same run without them;
- the Si's setup joints (S3) over every (site, pose) of the default's grid with the Si arms: the numpy batch
  (``si_docking.si_solutions``) against the plain ``reference.si_ik`` pose by pose, checked equal, and
  `surgopt port-place cart.model=si` end to end (the Si arms), docking alone and with the links deciding, with
  the dry run's estimates;
- the pruned least clearance between two arms (``capsules.least_between``, the link tables' kernel) against the
  exhaustive ``least_over_poses`` on the default's PSM pairs (their own links over 65 poses each), checked equal;
  and as the link tables take it (resolved up to CAP_M above the least) against a decision alone (clear or not).
"""
from __future__ import annotations

import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from surgopt.kinematics.port import suj_batch as B
from surgopt.robots.dvrk.platforms import PLATFORMS
from surgopt.studies.port_place import config as C
from surgopt.studies.port_place import study as S
from surgopt.studies.port_place import tables as T
from surgopt.studies.port_place import model as M

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import reference as REF  # noqa: E402 - the plain Python twin (S2, S3, S4) the batch solvers are timed against


def best_of(f, repeat=3):
    times, out = [], None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = f()
        times.append(time.perf_counter() - t0)
    return min(times), out


def solvers() -> None:
    cfg = C.PortPlaceConfig.model_validate({"cart": {"model": "classic"}})
    model = M.prepare(cfg)
    poses = T.cart_poses(cfg)
    n, m = len(model.sites_m), len(poses.floor)
    bases = np.zeros((n, 4, 4))
    bases[:, :3, :3], bases[:, :3, 3], bases[:, 3, 3] = model.instrument_rot, model.sites_m, 1.0
    in_cart = np.ascontiguousarray(np.einsum("pij,njk->npik", poses.patient, bases).reshape(n * m, 4, 4))
    suj = PLATFORMS["classic"].suj("PSM1")
    s = B.suj_arrays(suj)
    B.classic_psm_margins(s, in_cart[:2])  # compiled or loaded
    tj, got = best_of(lambda: B.classic_psm_margins(s, in_cart))
    sample = in_cart[:: max(1, len(in_cart) // 2000)]

    def plain():
        out = []
        for pose in sample:
            a = REF.classic_psm_ik(suj, pose)
            sols = a.within + a.outside
            out.append(sols[0].margin if sols else -math.inf)
        return np.array(out)

    tp, want = best_of(plain, repeat=1)
    same = np.array_equal(np.isinf(want), np.isinf(got[:: max(1, len(in_cart) // 2000)])) and np.allclose(
        want[np.isfinite(want)], got[:: max(1, len(in_cart) // 2000)][np.isfinite(want)], atol=1e-12)
    print(f"Classic PSM SUJ (S2), {n * m:,} (site, pose) cells: jitted {n * m / tj / 1e6:.2f} M solves/s "
          f"({tj * 1e6 / (n * m):.2f} us), plain Python {len(sample) / tp / 1e3:.1f} k solves/s "
          f"({tp * 1e6 / len(sample):.0f} us): {(tp / len(sample)) / (tj / (n * m)):.0f}x; equal: {same}")

    ecm = T.camera_arm_of(cfg)
    centre = np.asarray(cfg.target.centre_mm, float) / 1000
    shafts = T.camera_shafts(T.camera_of(cfg), centre, model.sites_m)
    some = poses.patient[:: max(1, m // 10)]

    def numpy_ecm():
        return [REF.ecm_classic_dock(PLATFORMS["classic"].suj("ECM"), ecm.yaw_limits_rad, ecm.pitch_limits_rad,
                                   model.sites_m @ p[:3, :3].T + p[:3, 3], shafts @ p[:3, :3].T)[0] for p in some]

    T.camera_dock(cfg, some[:1], model.sites_m[:2])  # compiled or loaded
    tn, want = best_of(numpy_ecm, repeat=1)
    tj, got = best_of(lambda: T.camera_dock(cfg, poses.patient, model.sites_m)[0], repeat=1)
    got = got.reshape(m, n)[:: max(1, m // 10)]
    want = np.array(want)
    same = np.array_equal(np.isinf(want), np.isinf(got)) and np.allclose(want[np.isfinite(want)],
                                                                         got[np.isfinite(want)], atol=1e-12)
    print(f"Classic ECM docking grid (S4, 36 x 36 x 12), per (site, pose): jitted {tj * 1e6 / (n * m):.0f} us, "
          f"numpy over the sites {tn * 1e6 / want.size:.0f} us: {(tn / want.size) / (tj / (n * m)):.1f}x; "
          f"equal: {same}")


SI_ARGS = ["cart.model=si", "robot.instrument_arm=dvrk_psm_si", "robot.camera_arm=dvrk_ecm_si"]


def si_solver() -> None:
    from surgopt.kinematics.port.si_docking import si_solutions

    cfg = C.PortPlaceConfig.model_validate({"cart": {"model": "si"}, "robot": {
        "instrument_arm": "dvrk_psm_si", "camera_arm": "dvrk_ecm_si"}})
    model = M.prepare(cfg)
    poses = T.cart_poses(cfg)
    n, m = len(model.sites_m), len(poses.floor)
    bases = np.zeros((n, 4, 4))
    bases[:, :3, :3], bases[:, :3, 3], bases[:, 3, 3] = model.instrument_rot, model.sites_m, 1.0
    in_cart = np.einsum("pij,njk->npik", poses.patient, bases).reshape(n * m, 4, 4)
    suj = PLATFORMS["si"].suj("PSM1")
    tb, (got, _) = best_of(lambda: si_solutions(suj, in_cart))
    step = max(1, len(in_cart) // 2000)

    def plain():
        out = []
        for pose in in_cart[::step]:
            a = REF.si_ik(suj, pose)
            sols = a.within + a.outside
            out.append(sols[0].margin if sols else -math.inf)
        return np.array(out)

    tp, want = best_of(plain, repeat=1)
    same = np.array_equal(np.isinf(want), np.isinf(got[::step])) and np.allclose(
        want[np.isfinite(want)], got[::step][np.isfinite(want)], atol=1e-12)
    print(f"Si PSM SUJ (S3), {n * m:,} (site, pose) cells at psi*: numpy batch {n * m / tb / 1e6:.2f} M solves/s "
          f"({tb * 1e6 / (n * m):.2f} us), plain Python {len(want) / tp / 1e3:.1f} k solves/s "
          f"({tp * 1e6 / len(want):.0f} us): {(tp / len(want)) / (tb / (n * m)):.0f}x; equal: {same}")


def end_to_end() -> None:
    took_without = {}  # per cart: the default grid's time with docking alone
    alone = "constraints.min_link_clearance_mm=off"  # docking alone: the links are in feasible by default
    for label, args in (("the default grid, docking alone", ["cart.model=classic", alone]),
                        ("a finer grid, docking alone", ["cart.model=classic", "cart.around_step_deg=7.5",
                                                         "cart.distance_step_mm=100", alone]),
                        ("the default grid, the links deciding (the default)", ["cart.model=classic"]),
                        ("the Si cart and arms, the default grid, docking alone", SI_ARGS + [alone]),
                        ("the Si cart and arms, the default grid, the links deciding", SI_ARGS)):
        si = "cart.model=si" in args
        cfg = C.PortPlaceConfig.model_validate({"cart": {"model": "si" if si else "classic", **{
            a.split("=")[0].split(".")[1]: float(a.split("=")[1]) for a in args[1:] if a.startswith("cart.")}},
            "robot": {"instrument_arm": "dvrk_psm_si", "camera_arm": "dvrk_ecm_si"} if si else {}})
        poses = len(T.cart_poses(cfg).floor)
        layouts = S.n_total(cfg)
        dry = subprocess.run([sys.executable, "-m", "surgopt", "port-place", *args, "--dry-run"],
                             capture_output=True, text=True).stdout
        cells = [c.strip() for line in dry.splitlines() if "port designs" in line for c in line.split("│")]
        est = next(float(c[:-2]) for c in cells if c.endswith(" s") and c[:-2].replace(".", "", 1).isdigit())
        with tempfile.TemporaryDirectory() as tmp:
            subprocess.run([sys.executable, "-m", "surgopt", "port-place", *args, "--store", tmp, "-q"], check=True,
                           capture_output=True)  # compiled or loaded once (the kernels' cache)
        with tempfile.TemporaryDirectory() as tmp:
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-m", "surgopt", "port-place", *args, "--store", tmp, "-q"], check=True,
                           capture_output=True)
            took = time.perf_counter() - t0
        pairs = layouts * poses
        print(f"surgopt port-place, {label} ({poses} cart poses), end to end (warm, 2 threads): {took:.1f} s for "
              f"{layouts:,} layouts x {poses} poses = {pairs:.3g} (layout, cart pose) pairs, {pairs / took:.3g} "
              f"pairs/s; the dry run's estimate {est:.1f} s ({est / took:.2f}x the time)"
              + (f"; {took / took_without[si]:.2f}x the run without the links" if "links deciding" in label else ""))
        took_without.setdefault(si, took)


def pruned_least() -> None:
    from surgopt.kinematics.port import capsules as Cap
    from surgopt.studies.port_place import link_tables as L

    cfg = C.PortPlaceConfig.model_validate({"cart": {"model": "classic"}})
    model = M.prepare(cfg)
    own, radii, groups = L.own_moving(model, model.sites_m, model.instrument_rot)
    balls = np.stack([Cap.swept_capsules(own[i], radii, groups) for i in range(len(own))])
    rng = np.random.default_rng(0)
    pairs = np.array([p for p in rng.integers(0, len(own), (400, 2)) if p[0] != p[1]][:300])
    Cap.moving_pairs(pairs[:2], own, balls, own, balls, radii, groups, np.inf, -np.inf)  # compiled or loaded
    Cap.least_over_poses(own[0], radii, own[1], radii)
    tp, (got, _) = best_of(lambda: Cap.moving_pairs(pairs, own, balls, own, balls, radii, groups, np.inf, -np.inf))
    te, want = best_of(lambda: np.array([Cap.least_over_poses(own[i], radii, own[j], radii)[0] for i, j in pairs]),
                       repeat=1)
    print(f"least clearance between two PSMs' own links over 65 x 65 poses, {len(pairs)} site pairs: pruned "
          f"{tp * 1e6 / len(pairs):.0f} us a pair, exhaustive {te * 1e6 / len(pairs):.0f} us: {te / tp:.1f}x; "
          f"equal: {bool(np.allclose(got, want, rtol=0, atol=1e-12))}")
    # what the tables do (resolved up to 100 mm above the least, stopped at the first overlap) against a decision
    # alone (clear of 0 or not: every ball pair farther than 0 pruned), the measure for a roll search in the tables
    tr, (resolved, _) = best_of(lambda: Cap.moving_pairs(pairs, own, balls, own, balls, radii, groups, L.CAP_M, 0.0))
    td, (decided, _) = best_of(lambda: Cap.moving_pairs(pairs, own, balls, own, balls, radii, groups, 1e-12, 0.0))
    print(f"the same pairs as the link tables take them (up to {L.CAP_M * 1000:.0f} mm above 0, stopped at an "
          f"overlap) {tr * 1e6 / len(pairs):.0f} us a pair, deciding clear or not alone {td * 1e6 / len(pairs):.0f} "
          f"us: {tr / td:.1f}x; the same decisions: {bool(np.array_equal(resolved >= 0, decided >= 0))}")


if __name__ == "__main__":
    solvers()
    si_solver()
    pruned_least()
    end_to_end()
