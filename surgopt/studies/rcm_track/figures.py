"""rcm-track figures: Figs. 4/5 style (reference and simulated tip path, error against time, for the kept
candidates) and Fig. 6 style (maximum tip error at each candidate over the GII map)."""
from __future__ import annotations

import numpy as np

from surgopt.studies.plotting import columns, pyplot, save


def _gii_map(cfg):
    """A coarse GII map (61 x 61 candidates, 9^3 cube) over the candidates' x-z box, for beneath Fig. 6."""
    from surgopt.studies.rcm_grid import study as grid

    xs = np.asarray(grid.candidate_xyz(cfg))
    pad = 0.05
    x0, x1 = xs[:, 0].min() - pad, xs[:, 0].max() + pad
    z0, z1 = xs[:, 2].min() - pad, xs[:, 2].max() + pad
    g = grid.Grid(x_min_m=x0, x_max_m=x1, x_count=61, y_min_m=xs[0, 1], y_max_m=xs[0, 1], y_count=1,
                  z_min_m=z0, z_max_m=z1, z_count=61)
    mcfg = grid.RcmGridConfig.model_validate(
        {"robot": cfg.robot.model_dump(), "workspace": {**cfg.workspace.model_dump(), "points_per_side": 9},
         "candidates": {"z_reference": cfg.candidates.z_reference, "grid": g.model_dump()}},
        context={"stored": True})
    rows = grid.compute_task(mcfg, 61 * 61, 0)
    gii = np.where(rows["feasible"], rows["gii"], np.nan).reshape(61, 61)
    return np.linspace(x0, x1, 61), np.linspace(z0, z1, 61), gii


def figures(cfg, table, out, design_id=None):
    from surgopt.studies.rcm_grid.figures import robot_title
    from surgopt.studies.rcm_track.study import reference_path

    plt = pyplot()
    c = columns(table)
    paths = []
    t_ref, off, _ = reference_path(cfg)
    kept = [i for i, tr in enumerate(table["trace_t_s"].to_pylist()) if tr]
    if design_id is not None:
        kept = [i for i in kept if c["candidate_id"][i] == design_id]
    from surgopt.studies.rcm_grid import study as grid

    for i in kept:
        cid = int(c["candidate_id"][i])
        rcm = grid.candidate_rcms(cfg, np.array([[c["x_rcm_m"][i], c["y_rcm_m"][i], c["z_rcm_m"][i]]]))[0]
        ref = (rcm + off) * 1e3
        tr = {k: np.array(table[f"trace_{k}"][i].as_py()) for k in ("t_s", "tip_x_m", "tip_y_m", "tip_z_m",
                                                                   "tip_error_mm", "rcm_error_mm")}
        fig = plt.figure(figsize=(10, 4.2))
        ax = fig.add_subplot(1, 2, 1, projection="3d")
        ax.plot(ref[:, 0], ref[:, 1], ref[:, 2], "k--", lw=0.8, label="reference")
        ax.plot(tr["tip_x_m"] * 1e3, tr["tip_y_m"] * 1e3, tr["tip_z_m"] * 1e3, "C3", lw=1.0, label="simulated tip")
        ax.set_xlabel("x (mm)")
        ax.set_ylabel("y (mm)")
        ax.set_zlabel("z (mm)")
        ax.legend(fontsize=7, loc="upper left")
        ax.set_title(f"RCM ({c['x_rcm_m'][i]:.3f}, {c['y_rcm_m'][i]:.3f}, {c['z_rcm_m'][i]:.3f}) m, "
                     f"GII {c['gii'][i]:.4f}", fontsize=9)
        fig.subplots_adjust(wspace=0.4)
        ax2 = fig.add_subplot(1, 2, 2)
        ax2.plot(tr["t_s"], tr["tip_error_mm"], label="tip error")
        ax2.plot(tr["t_s"], tr["rcm_error_mm"], label="RCM error (RCM to tool line)")
        ax2.set_xlabel("t (s)")
        ax2.set_ylabel("error (mm)")
        ax2.set_title(f"max tip error {c['max_tip_error_mm'][i]:.1f} mm; saturated {c['saturated_s'][i]:.2f} s\n"
                      f"gain {cfg.track.gain_per_s:g}/s, lag {cfg.track.velocity_lag_s:g} s, {robot_title(cfg)}",
                      fontsize=9)
        ax2.legend(fontsize=8)
        paths.append(save(fig, out / f"rcm_track_candidate_{cid}.png"))
    f = c["feasible"].astype(bool)
    if f.sum() >= 2:
        xs, zs, gii = _gii_map(cfg)
        fig, ax = plt.subplots(figsize=(6.4, 5.6))
        im = ax.pcolormesh(xs, zs, gii.T, shading="nearest", cmap="viridis")
        fig.colorbar(im, ax=ax, label="GII (61 x 61 map, 9^3 cube)")
        e = c["max_tip_error_mm"][f]
        sc = ax.scatter(c["x_rcm_m"][f], c["z_rcm_m"][f], s=20 + 8 * e, c=e, cmap="Reds", edgecolors="white",
                        linewidths=0.8, zorder=3)
        fig.colorbar(sc, ax=ax, label="max tip error (mm)")
        for x, z, v in zip(c["x_rcm_m"][f], c["z_rcm_m"][f], e):
            ax.annotate(f"{v:.1f}", (x, z), xytext=(6, 5), textcoords="offset points", fontsize=7, color="black",
                        bbox=dict(boxstyle="round,pad=0.15", fc="white", alpha=0.75, lw=0))
        ax.set_xlabel("x_rcm (m)")
        ax.set_ylabel(f"z_rcm (m, from the {cfg.candidates.z_reference})")
        ax.set_aspect("equal")
        ax.set_title("Maximum tip error along the helical test path (Fig. 6 style)", fontsize=10)
        paths.append(save(fig, out / "rcm_track_max_error.png"))
    return paths
