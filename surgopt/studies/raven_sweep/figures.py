"""raven-sweep figures: a design's common workspace, zeta over (alpha, beta) per Iso_min (Fig. 7 style),
and the theta2 range kept by Iso_min (Fig. 6 style)."""
from __future__ import annotations

import math

import numpy as np

from surgopt.kinematics.raven import isotropy_at, theta2_interval
from surgopt.studies.plotting import columns, pyplot, save
from surgopt.studies.raven_sweep.study import PARAMS, design_fields, paper_optimum_rank


def _workspace_panel(ax, plt, cfg, params, title):
    xs, ys, ports, margins, common = design_fields(cfg, params)
    ax.contourf(xs, ys, common.T, levels=[0, np.inf], colors=["#9ecae1"])
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for a in range(margins.shape[0]):
        ax.contour(xs, ys, margins[a].T, levels=[0], colors=[colors[a % len(colors)]], linewidths=1)
        ax.plot(*ports[a, :2], "^", color=colors[a % len(colors)])
    ax.set_aspect("equal")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_title(title, fontsize=9)


def _fig8(plt, cfg, table, c, best):
    """Fig. 8 style: the paper's optimal design's common workspace beside our best design's, when the
    table holds the paper's optimum (Table II's sweep)."""
    found = paper_optimum_rank(table)
    if found is None:
        return None
    rank, row = found
    k = int(np.flatnonzero(c["design_id"] == row["design_id"])[0])
    fig, axes = plt.subplots(1, 2, figsize=(11, 5.2))
    for ax, j, who in ((axes[0], k, f"the paper's optimum (rank {rank:,} here)"), (axes[1], best, "our best design")):
        params = {p: float(c[p][j]) for p in PARAMS}
        _workspace_panel(ax, plt, cfg, params, "{}: ζ {:.2f} cm, C {:,.0f}\n(α {alpha_deg:g}°, β {beta_deg:g}°, φ "
                         "{phi_x_deg:g}/{phi_y_deg:g}/{phi_z_deg:g}°, b {bx_mm:g}×{by_mm:g} mm, Iso_min {iso_min:g})"
                         .format(who, c["zeta_cm"][j], c["cost"][j], **params))
    fig.suptitle("Fig. 8 style: the common workspace of four arms on the reference plane", fontsize=10)
    return fig


def figures(cfg, table, out, design_id=None):
    plt = pyplot()
    c = columns(table)
    paths = []
    i = int(np.argmax(c["cost"])) if design_id is None else int(np.flatnonzero(c["design_id"] == design_id)[0])
    params = {p: float(c[p][i]) for p in PARAMS}
    xs, ys, ports, margins, common = design_fields(cfg, params)
    fig, ax = plt.subplots(figsize=(6.4, 6))
    ax.contourf(xs, ys, common.T, levels=[0, np.inf], colors=["#9ecae1"])
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for a in range(margins.shape[0]):
        ax.contour(xs, ys, margins[a].T, levels=[0], colors=[colors[a % len(colors)]], linewidths=1)
        ax.plot(*ports[a, :2], "^", color=colors[a % len(colors)], label=f"arm {a + 1} port")
    ax.set_aspect("equal")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_title("common workspace {:.0f} cm², ζ = {:.2f} cm\n(α {alpha_deg:g}°, β {beta_deg:g}°, φ {phi_x_deg:g}/{phi_y_deg:g}/"
                 "{phi_z_deg:g}°, b {bx_mm:g}×{by_mm:g} mm, Iso_min {iso_min:g})".format(
                     c["area_cm2"][i], c["zeta_cm"][i], **params), fontsize=9)
    ax.legend(fontsize=7, loc="upper right")
    paths.append(save(fig, out / "raven_workspace.png"))
    fig8 = _fig8(plt, cfg, table, c, i)
    if fig8 is not None:
        paths.append(save(fig8, out / "raven_fig8.png"))
    # zeta over (alpha, beta): best over the other parameters, one panel per Iso_min (Fig. 7)
    al, be, iso = (np.unique(c[p]) for p in ("alpha_deg", "beta_deg", "iso_min"))
    if al.size > 1 and be.size > 1:
        panels = []
        for m in iso:
            Z = np.full((al.size, be.size), np.nan)
            for a_i, a in enumerate(al):
                for b_i, b in enumerate(be):
                    sel = (c["alpha_deg"] == a) & (c["beta_deg"] == b) & (c["iso_min"] == m)
                    Z[a_i, b_i] = c["zeta_cm"][sel].max() if sel.any() else np.nan
            panels.append(Z)
        top = max(float(np.nanmax(Z)) for Z in panels)
        cmap = plt.get_cmap("magma").copy()
        cmap.set_bad("#d9d9d9")  # grey: no common workspace (zeta 0) or no design there
        fig, axes = plt.subplots(1, iso.size, figsize=(4.2 * iso.size + 1.2, 3.8), squeeze=False)
        for k, (m, Z) in enumerate(zip(iso, panels)):
            ax = axes[0, k]
            im = ax.pcolormesh(be, al, np.ma.masked_where(~(Z > 0), Z), shading="nearest", cmap=cmap, vmin=0, vmax=top)
            j = np.unravel_index(np.nanargmax(Z), Z.shape)
            ax.plot(be[j[1]], al[j[0]], "c+", ms=9, mew=2)
            ax.set_title(f"Iso_min {m:g}: ζ max {np.nanmax(Z):.2f} at α {al[j[0]]:g}, β {be[j[1]]:g}", fontsize=9)
            ax.set_xlabel("β (deg)")
            ax.set_ylabel("α (deg)")
        fig.colorbar(im, ax=axes[0].tolist(), label="ζ (cm); grey: no common workspace")
        paths.append(save(fig, out / "raven_zeta_alpha_beta.png"))
    # theta2 range against Iso_min (Fig. 6) for the chosen design's links
    a, b = math.radians(params["alpha_deg"]), math.radians(params["beta_deg"])
    lo, hi = (math.radians(v) for v in cfg.geometry.theta2_range_deg)
    t = np.linspace(0, math.pi, 721)
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(np.degrees(t), [isotropy_at(x, a, b) for x in t], label="Iso(θ2)")
    for m in (0.1, 0.3, 0.5, 0.7, 0.9):
        tl, th, ok = theta2_interval(a, b, m, lo, hi)
        if ok:
            ax.hlines(m, math.degrees(tl), math.degrees(th), colors="C3", lw=3)
            ax.text(math.degrees(th) + 2, m, f"{math.degrees(tl):.0f}–{math.degrees(th):.0f}°", fontsize=7, va="center")
    ax.axvspan(0, math.degrees(lo), color="0.9")
    ax.axvspan(math.degrees(hi), 180, color="0.9")
    ax.set_xlabel("θ2 (deg)")
    ax.set_ylabel("isotropy")
    ax.set_title(f"θ2 range kept by Iso_min (α {params['alpha_deg']:g}°, β {params['beta_deg']:g}°); grey: outside Table I",
                 fontsize=9)
    paths.append(save(fig, out / "raven_theta2_iso.png"))
    return paths
