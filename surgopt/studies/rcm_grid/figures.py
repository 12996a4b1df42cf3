"""rcm-grid figures: the GII map of Locke & Patel's Fig. 3 and the Table I scatter."""
from __future__ import annotations

import numpy as np

from surgopt.studies.plotting import columns, pyplot, save
from surgopt.studies.rcm_grid.study import PAPER_TABLE_I


def robot_title(cfg) -> str:
    """The arm's name for a figure: the shipped model's title, or the URDF file's / "DH table"."""
    from pathlib import Path

    from surgopt.robots.models import get_model

    r = cfg.robot
    if r.model is not None:
        return get_model(r.model).title + (" (generic kernel)" if r.is_pa10 and not r.closed_form else "")
    return Path(r.urdf).name if r.urdf else "DH table"


def contour_levels(top) -> list[float]:
    """The paper's Fig. 3 contours (0.01 ... 0.04) when the map's GII stays below 0.05, else about five
    round levels below its maximum."""
    if not np.isfinite(top) or top <= 0.05:
        return [0.01, 0.02, 0.03, 0.04]
    from matplotlib.ticker import MaxNLocator

    return [v for v in MaxNLocator(nbins=5).tick_values(0.0, top) if 0.0 < v < top]


def figures(cfg, table, out, design_id=None):
    plt = pyplot()
    c = columns(table)
    paths = []
    exact = c["gii_is_exact"]
    if cfg.candidates.grid is not None and cfg.search == "full":
        g = cfg.candidates.grid
        gii = np.full((g.x_count, g.y_count, g.z_count), np.nan)
        ids = c["candidate_id"]
        vals = np.where(c["feasible"], c["gii"], np.nan)
        gii.ravel()[ids] = vals
        with np.errstate(all="ignore"):  # the best over y where the grid has a y range; all-NaN stays NaN
            gii = np.nanmax(np.where(np.isnan(gii), -np.inf, gii), axis=1)
        gii[~np.isfinite(gii)] = np.nan
        xs = np.linspace(g.x_min_m, g.x_max_m, g.x_count)
        zs = np.linspace(g.z_min_m, g.z_max_m, g.z_count)
        fig, ax = plt.subplots(figsize=(6.4, 5.6))
        im = ax.pcolormesh(xs, zs, gii.T, shading="nearest", cmap="viridis")
        fig.colorbar(im, ax=ax, label="GII")
        cs = ax.contour(xs, zs, np.nan_to_num(gii.T, nan=0.0), levels=contour_levels(np.nanmax(gii)),
                        colors="white", linewidths=0.8)
        ax.clabel(cs, fmt="%.2f", fontsize=7)
        i = int(np.nanargmax(np.where(exact, c["gii"], np.nan)))
        ax.plot(c["x_rcm_m"][i], c["z_rcm_m"][i], "wx", ms=10, mew=2)
        # the label points into the map (away from the nearer edges), on a dark box readable on yellow
        right = c["x_rcm_m"][i] > 0.5 * (g.x_min_m + g.x_max_m)
        above = c["z_rcm_m"][i] > 0.5 * (g.z_min_m + g.z_max_m)
        ax.annotate(f"best ({c['x_rcm_m'][i]:.3f}, {c['z_rcm_m'][i]:.3f}) m\nGII {c['gii'][i]:.4f}",
                    (c["x_rcm_m"][i], c["z_rcm_m"][i]), xytext=(-12 if right else 12, -12 if above else 12),
                    textcoords="offset points", ha="right" if right else "left", va="top" if above else "bottom",
                    color="white", fontsize=8, bbox=dict(boxstyle="round,pad=0.3", fc="black", alpha=0.6, lw=0),
                    arrowprops=dict(arrowstyle="-", color="white", lw=0.8))
        ax.set_xlabel("x_rcm (m)")
        ax.set_ylabel(f"z_rcm (m, from the {cfg.candidates.z_reference})")
        over_y = f", best over y in [{g.y_min_m:g}, {g.y_max_m:g}] m" if g.y_count > 1 else ""
        ax.set_title(f"GII of candidate RCM locations: {robot_title(cfg)}{over_y}\n"
                     f"(white: part of the workspace unreachable)", fontsize=10)
        ax.set_aspect("equal")
        paths.append(save(fig, out / "rcm_gii_map.png"))
    if not cfg.robot.is_pa10:
        return paths
    paper = {(round(x, 3), round(z, 3)): g for x, z, g in PAPER_TABLE_I}
    pairs = [(paper[(round(x, 3), round(z, 3))], g) for x, z, g in zip(c["x_rcm_m"], c["z_rcm_m"], c["gii"])
             if (round(x, 3), round(z, 3)) in paper]
    if pairs:
        p, o = np.array(pairs).T
        fig, ax = plt.subplots(figsize=(5, 5))
        ax.plot(p, o, "o")
        lim = [0, max(p.max(), o.max()) * 1.1]
        ax.plot(lim, lim, "k--", lw=0.8, label="equal")
        ax.set_xlabel("paper's GII (Table I)")
        ax.set_ylabel("surgopt GII")
        r = f", Pearson r = {np.corrcoef(p, o)[0, 1]:.4f}" if len(p) > 1 and np.ptp(p) > 0 and np.ptp(o) > 0 else ""
        ax.set_title(f"Table I: {len(p)} RCM location(s){r}")  # one point (or a flat set) has no correlation
        ax.legend()
        paths.append(save(fig, out / "rcm_table1_scatter.png"))
    return paths
