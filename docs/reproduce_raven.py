"""Regenerate the numbers of docs/reproduction.md, Raven section (Li et al., ICRA 2011).

Run:  python docs/reproduce_raven.py   (about 15 s on 2 cores once the kernels are compiled: Fig. 4's two designs,
      Fig. 7's three port spacings, ten full Table II sweeps, one per geometry below, and a refine)
"""
from __future__ import annotations

import copy
import tempfile
from pathlib import Path

import numpy as np

from surgopt.config import load_config, load_embedded
from surgopt.plans import follow_up_plan
from surgopt.runner import run_study
from surgopt.store import Store
from surgopt.studies.raven_sweep import study as S

REPO = Path(__file__).resolve().parents[1]


def changed(cfg, **kw):
    d = copy.deepcopy(cfg.model_dump())
    for path, v in kw.items():
        sec, key = path.split("__")
        d[sec][key] = v
    return S.Config.model_validate(d)


def rows(cfg):
    parts = [S.compute_task(cfg, 10_000, i) for i in range(S.n_tasks(cfg, 10_000))]
    return {k: np.concatenate([np.asarray(p[k]) for p in parts]) for k in parts[0]}


def main():
    fig4 = rows(load_config(REPO / "configs" / "raven_fig4.toml", S.Config))
    print("Fig. 4 (two arms, vertical shoulder axes, theta2 0-180, ports 100 mm apart):")
    for a, b, z, paper in ((15, 15, None, 2.23), (65, 80, None, 4.48)):
        i = np.flatnonzero((fig4["alpha_deg"] == a) & (fig4["beta_deg"] == b))[0]
        print(f"  alpha {a} beta {b}: zeta {fig4['zeta_cm'][i]:.3f} cm (paper {paper}, {100 * (fig4['zeta_cm'][i] / paper - 1):+.1f}%)")

    f7 = load_config(REPO / "configs" / "raven_fig7.toml", S.Config)
    print("\nFig. 7 (four arms, zeta max over alpha, beta in 5 deg steps; paper 6.64 at 80/40 for Iso_min 0, "
          "6.55 at 70/35 for 0.5):")
    for bx, by in ((50, 50), (100, 50), (100, 100)):
        r = rows(changed(f7, sweep__bx_mm=[bx], sweep__by_mm=[by]))
        cells = []
        for m in (0.0, 0.5):
            sel = r["iso_min"] == m
            i = np.argmax(np.where(sel, r["zeta_cm"], -1))
            cells.append(f"Iso_min {m}: {r['zeta_cm'][i]:.2f} at {r['alpha_deg'][i]:.0f}/{r['beta_deg'][i]:.0f}")
        print(f"  ports {bx} x {by} mm: " + "; ".join(cells))

    base = load_embedded(S.DEFAULT_CONFIG, S.Config)
    variants = {
        "default: horizontal axes (outward along x), theta2 [20, 140], mirrored, theta1 [0, 90] (Raven II)": {},
        "theta1 unlimited": dict(geometry__theta1_range_deg=[-180.0, 180.0]),
        "theta1 [0, 180]": dict(geometry__theta1_range_deg=[0.0, 180.0]),
        "theta2 [0, 180]": dict(geometry__theta2_range_deg=[0.0, 180.0]),
        "axes tilted 75 deg": dict(geometry__shoulder_tilt_deg=75.0),
        "axes tilted 45 deg": dict(geometry__shoulder_tilt_deg=45.0),
        "vertical axes": dict(geometry__shoulder_tilt_deg=0.0),
        "vertical axes, theta2 [0, 180]": dict(geometry__shoulder_tilt_deg=0.0, geometry__theta2_range_deg=[0.0, 180.0]),
        "horizontal, outward along y": dict(geometry__shoulder_tilt_toward="y"),
        "horizontal, phi not mirrored for left arms": dict(geometry__mirror_left_phi=False),
    }
    print("\n| geometry | paper optimum: C | rank of 250,000 | best design (alpha, beta, phi_x, phi_y, phi_z, bx, by, Iso_min) | best C |")
    print("|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for name, ch in variants.items():
            cfg = changed(base, **ch) if ch else base
            res = run_study(S.STUDY, cfg, config_name=name, store=Store(tmp), jobs=2, quiet=True)
            t = res.table
            rank, row = S.paper_optimum_rank(t)
            i = int(np.argmax(t["cost"].to_numpy()))
            best = ", ".join(f"{t[p][i].as_py():g}" for p in S.PARAMS)
            print(f"| {name} | {row['cost']:.1f} | {rank} | ({best}) | {t['cost'][i].as_py():.1f} |")
            if not ch:
                default_table, default_res, res_cfg = t, res, cfg
        refine = run_study(S.STUDY, res_cfg, plan=follow_up_plan("refine", S.STUDY, res_cfg, default_res),
                           config_name="refine", store=Store(tmp), jobs=2, quiet=True)
        t = refine.table
        i = int(np.argmax(t["cost"].to_numpy()))
        print("\n--refine from the top 5:", ", ".join(f"{p} {t[p][i].as_py():.4g}" for p in S.PARAMS),
              f"C {t['cost'][i].as_py():.1f} (grid best {default_table['cost'].to_numpy().max():.1f}); "
              f"{t.num_rows} designs evaluated")
        r = S.paper_optimum_rank(default_table)[1]
        print("\npaper optimum under the default geometry:", {k: (round(v, 3) if isinstance(v, float) else v)
                                                              for k, v in r.items()})
        d = default_table.to_pandas()
        b = d.loc[d["cost"].idxmax()]
        print(f"our best: zeta {b.zeta_cm:.2f} cm, area {b.area_cm2:.1f} cm2, C {b.cost:.1f}")
        top = d[d["iso_min"] == 0.9].groupby(["alpha_deg", "beta_deg"])["zeta_cm"].max()
        print("Iso_min 0.9, (alpha, beta) pairs with a common workspace, best zeta (cm):",
              ", ".join(f"({a:g}, {b_:g}) {z:.2f}" for (a, b_), z in top[top > 0].sort_values(ascending=False).items()))
    insertion_limit_effect(base)
    fig6_intervals()


def insertion_limit_effect(cfg):
    """Table II with a node exactly d4 = 250 mm from its farthest port inside (Table I's closed range, the
    default) against outside (the limit a hair shorter): which designs move, and by how much."""
    import math

    sw = cfg.sweep
    al, be, iso = (S.values(v) for v in (sw.alpha_deg, sw.beta_deg, sw.iso_min))
    geos = S.geometry_grid(cfg)
    closed = S.evaluate(cfg, geos, al, be, iso)
    shorter = cfg.geometry.model_copy(update={"d4_max_mm": math.nextafter(cfg.geometry.d4_max_mm, 0.0)})
    opened = S.evaluate(cfg.model_copy(update={"geometry": shorter}), geos, al, be, iso)
    n1, n0 = closed[:, 2], opened[:, 2]
    moved = n1 != n0
    rel = (n1 - n0)[moved] / n1[moved]
    big = moved & (n1 >= 1000)
    spacing = np.repeat(np.array(geos)[:, 3:5], len(al) * len(be) * len(iso), axis=0)[moved]
    print(f"\nd4 = 250 mm closed: {moved.sum():,} of {len(n1):,} designs gain {int((n1 - n0)[moved].min())}-"
          f"{int((n1 - n0).max())} nodes (n: median +{100 * np.median(rel):.2f}%, 99th percentile "
          f"+{100 * np.percentile(rel, 99):.1f}%, max +{100 * rel.max():.1f}%; designs of >= 1,000 nodes: at most "
          f"+{100 * ((n1 - n0)[big] / n1[big]).max():.1f}%); spacings (bx, by) of those moved: "
          f"{sorted(set(map(tuple, spacing.tolist())))}; largest area / perimeter change "
          f"{np.abs(closed[:, :2] - opened[:, :2]).max():.1e}")


def fig6_intervals():
    """Fig. 6 (alpha 55 deg, beta 40 deg): the theta2 interval each Iso_min keeps and Iso's maximum over theta2."""
    from surgopt.kinematics import raven as K

    a, b = np.radians(55.0), np.radians(40.0)
    cells = []
    for m in (0.1, 0.3, 0.5, 0.7, 0.9):
        lo, hi, _ = K.theta2_interval(a, b, m, 0.0, np.pi)
        cells.append(f"Iso >= {m}: [{np.degrees(lo):.1f}, {np.degrees(hi):.1f}]")
    t2 = np.radians(np.arange(0.0, 180.0, 0.01))
    iso = np.array([K.isotropy_at(t, a, b) for t in t2])
    k = int(np.argmax(iso))
    print("\nFig. 6 (alpha 55, beta 40), theta2 in deg: " + "; ".join(cells) +
          f"; Iso max {iso[k]:.3f} at {np.degrees(t2[k]):.1f}")


if __name__ == "__main__":
    main()
