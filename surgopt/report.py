"""Tables and figures of stored runs (matplotlib, Agg backend). Knows studies only through their
module attributes (NAME, OBJECTIVE, feasibility, tables, ...) and, for figures, their helpers."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

STATS = ("count", "min", "p25", "median", "p75", "max", "mean")


def _df(table):
    import pyarrow as pa

    # plain numpy/object columns: no dependence on pandas' string dtype
    return {name: (col.to_numpy(zero_copy_only=False) if not pa.types.is_string(col.type) else
                   np.array(col.to_pylist(), dtype=object)) for name, col in zip(table.column_names, table.columns)}


def summary_sections(study, run, table, top: int = 10, sort: str | None = None) -> list[tuple[str, list[str], list[list]]]:
    """Study-aware summary: header, top designs, objective statistics, feasibility, study tables."""
    done, total = len(run.manifest["parts"]), run.manifest["n_tasks"]
    state = "complete" if done == total else f"PARTIAL: {done} of {total} chunks stored (rerun the study to finish)"
    head = [["study", study.NAME], ["key", run.key[:12]], ["config", run.manifest.get("config_name", "?")],
            ["rows", table.num_rows], ["state", state], ["created", run.manifest.get("created", "?")]]
    head += [[k, v] for k, v in study.feasibility(table).items()] if table.num_rows else []
    sections = [("run", ["field", "value"], head)]
    objective = sort or study.OBJECTIVE
    cols = _df(table)
    if objective is not None and table.num_rows:
        if objective not in cols:
            from surgopt.errors import UsageError

            raise UsageError(f"--sort: no column {objective!r}; columns: {', '.join(table.column_names)}")
        order = np.argsort(-cols[objective].astype(float), kind="stable")[:top]
        names = [c for c in table.column_names if cols[c].dtype != object or c in study.KEY_COLUMNS]
        sections.append((f"top {len(order)} by {objective}", names,
                         [[_fmt(cols[c][i]) for c in names] for i in order]))
        rows = []
        for label, v in (("all", cols[objective].astype(float)),
                         ("feasible", cols[objective].astype(float)[study.feasible_mask(table)])):
            if v.size:
                q = np.percentile(v, [0, 25, 50, 75, 100])
                rows.append([label, len(v)] + [_fmt(x) for x in q] + [_fmt(v.mean())])
        sections.append((f"distribution of {objective}", ["rows"] + list(STATS), rows))
    if table.num_rows and study.OBJECTIVE is None:
        for title, header, rows in study.tables(table):
            sections.append((title, header, rows))
    return sections


def _fmt(x):
    if isinstance(x, (float, np.floating)):
        return float(f"{x:.6g}")
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def render(sections, fmt: str) -> str:
    if fmt == "json":
        return json.dumps({title: [dict(zip(header, row)) for row in rows] for title, header, rows in sections},
                          indent=1, default=str)
    out = []
    for title, header, rows in sections:
        if fmt == "csv":
            import csv
            import io

            buf = io.StringIO()
            buf.write(f"# {title}\n")
            w = csv.writer(buf)
            w.writerow(header)
            w.writerows(rows)
            out.append(buf.getvalue())
        else:  # markdown
            cell = lambda v: str(v).replace("|", "\\|")  # noqa: E731
            out.append(f"### {title}\n\n| " + " | ".join(map(cell, header)) + " |\n|" + "---|" * len(header) + "\n"
                       + "".join("| " + " | ".join(map(cell, r)) + " |\n" for r in rows))
    return "\n".join(out)


# ---------------------------------------------------------------------------
# figures
# ---------------------------------------------------------------------------


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def figures(study, cfg, table, out_dir: Path, design_id: int | None = None) -> list[Path]:
    out_dir.mkdir(parents=True, exist_ok=True)
    return {"rcm-grid": _rcm_figures, "raven-sweep": _raven_figures,
            "suture-sim": _suture_figures}[study.NAME](study, cfg, table, out_dir, design_id)


def _save(fig, path: Path) -> Path:
    fig.savefig(path, dpi=110, bbox_inches="tight")
    _plt().close(fig)
    return path


def _rcm_figures(study, cfg, table, out, design_id):
    plt = _plt()
    c = _df(table)
    paths = []
    exact = c["gii_is_exact"]
    if cfg.candidates.grid is not None and cfg.search == "full":
        g = cfg.candidates.grid
        gii = np.full((g.x_count, g.z_count), np.nan)
        ids = c["candidate_id"]
        vals = np.where(c["feasible"], c["gii"], np.nan)
        gii.ravel()[ids] = vals
        xs = np.linspace(g.x_min_m, g.x_max_m, g.x_count)
        zs = np.linspace(g.z_min_m, g.z_max_m, g.z_count)
        fig, ax = plt.subplots(figsize=(6.4, 5.6))
        im = ax.pcolormesh(xs, zs, gii.T, shading="nearest", cmap="viridis")
        fig.colorbar(im, ax=ax, label="GII")
        cs = ax.contour(xs, zs, np.nan_to_num(gii.T, nan=0.0), levels=[0.01, 0.02, 0.03, 0.04], colors="white",
                        linewidths=0.8)
        ax.clabel(cs, fmt="%.2f", fontsize=7)
        i = int(np.nanargmax(np.where(exact, c["gii"], np.nan)))
        ax.plot(c["x_rcm_m"][i], c["z_rcm_m"][i], "wx", ms=10, mew=2)
        ax.annotate(f"best ({c['x_rcm_m'][i]:.3f}, {c['z_rcm_m'][i]:.3f}) m\nGII {c['gii'][i]:.4f}",
                    (c["x_rcm_m"][i], c["z_rcm_m"][i]), xytext=(8, 8), textcoords="offset points", color="white",
                    fontsize=8)
        ax.set_xlabel("x_rcm (m)")
        ax.set_ylabel(f"z_rcm (m, from the {cfg.candidates.z_reference})")
        ax.set_title("GII of candidate RCM locations\n(white: part of the workspace unreachable)", fontsize=10)
        ax.set_aspect("equal")
        paths.append(_save(fig, out / "rcm_gii_map.png"))
    paper = {(round(x, 3), round(z, 3)): g for x, z, g in study.PAPER_TABLE_I}
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
        r = np.corrcoef(p, o)[0, 1]
        ax.set_title(f"Table I: {len(p)} RCM locations, Pearson r = {r:.4f}")
        ax.legend()
        paths.append(_save(fig, out / "rcm_table1_scatter.png"))
    return paths


def _raven_figures(study, cfg, table, out, design_id):
    from surgopt.kinematics.raven import isotropy_at, theta2_interval

    plt = _plt()
    c = _df(table)
    paths = []
    i = int(np.argmax(c["cost"])) if design_id is None else int(np.flatnonzero(c["design_id"] == design_id)[0])
    params = {p: float(c[p][i]) for p in study.PARAMS}
    xs, ys, ports, margins, common = study.design_fields(cfg, params)
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
    paths.append(_save(fig, out / "raven_workspace.png"))
    # zeta over (alpha, beta): best over the other parameters, one panel per Iso_min (Fig. 7)
    al, be, iso = (np.unique(c[p]) for p in ("alpha_deg", "beta_deg", "iso_min"))
    if al.size > 1 and be.size > 1:
        fig, axes = plt.subplots(1, iso.size, figsize=(4.2 * iso.size, 3.8), squeeze=False)
        for k, m in enumerate(iso):
            Z = np.full((al.size, be.size), np.nan)
            for a_i, a in enumerate(al):
                for b_i, b in enumerate(be):
                    sel = (c["alpha_deg"] == a) & (c["beta_deg"] == b) & (c["iso_min"] == m)
                    Z[a_i, b_i] = c["zeta_cm"][sel].max() if sel.any() else np.nan
            ax = axes[0, k]
            im = ax.pcolormesh(be, al, Z, shading="nearest", cmap="magma")
            fig.colorbar(im, ax=ax, label="ζ (cm)")
            j = np.unravel_index(np.nanargmax(Z), Z.shape)
            ax.set_title(f"Iso_min {m:g}: ζ max {np.nanmax(Z):.2f} at α {al[j[0]]:g}, β {be[j[1]]:g}", fontsize=9)
            ax.set_xlabel("β (deg)")
            ax.set_ylabel("α (deg)")
        fig.tight_layout()
        paths.append(_save(fig, out / "raven_zeta_alpha_beta.png"))
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
    paths.append(_save(fig, out / "raven_theta2_iso.png"))
    return paths


def _suture_figures(study, cfg, table, out, design_id):
    from surgopt.kinematics.throat import forward_kinematics

    plt = _plt()
    c = _df(table)
    paths = []
    keys = ["arm_length_mm", "fulcrum_to_tip_mm", "mode", "radius_mm", "speed_mm_s"]
    combos = sorted({tuple(c[k][i] for k in keys) for i in np.unique(c["run_id"], return_index=True)[1]},
                    key=lambda t: (t[0], t[1], t[2]))
    for n_combo, combo in enumerate(combos):
        sel = np.ones(len(c["run_id"]), bool)
        for k, v in zip(keys, combo):
            sel &= c[k] == v
        sets = list(dict.fromkeys(c["weight_set"][sel]))
        fig, axes = plt.subplots(1, len(sets), figsize=(5.2 * len(sets), 3.8), squeeze=False, sharey=True)
        for k, w in enumerate(sets):
            s = sel & (c["weight_set"] == w)
            ax = axes[0, k]
            for j, name in enumerate(study.NORM_COLUMNS):
                ax.plot(c["t_s"][s], c[name][s], label=study.JOINT_COLUMNS[j])
            ax.axhline(1.0, color="k", lw=0.6, ls="--")
            ax.set_title(f"{w}", fontsize=9)
            ax.set_xlabel("t (s)")
        axes[0, 0].set_ylabel("|q_i / q_imax|")
        axes[0, -1].legend(fontsize=7, loc="center left", bbox_to_anchor=(1, 0.5))
        fig.suptitle("joint motion, arm {:.0f} mm, fulcrum {:.0f} mm, {}, r {:g} mm at {:g} mm/s".format(*combo), fontsize=9)
        paths.append(_save(fig, out / f"suture_joints_{n_combo}.png"))
        # the tracked path of the platform (and of a needle tip held radius off its axis)
        geo = study.geometry(cfg, combo[0], combo[1])
        fig, ax = plt.subplots(figsize=(5, 5))
        for w in sets:
            s = sel & (c["weight_set"] == w)
            qs = np.column_stack([c[name][s] for name in study.JOINT_COLUMNS])
            poses = [forward_kinematics(q, geo) for q in qs[:: max(1, len(qs) // 400)]]
            p0, R0 = poses[0]
            pts = np.array([R0.T @ (p - p0) for p, _ in poses])
            needle = np.array([R0.T @ (p + combo[3] * R[:, 0] - p0) for p, R in poses])
            ax.plot(pts[:, 0], pts[:, 1], label=f"{w}: platform")
            ax.plot(needle[:, 0], needle[:, 1], "--", label=f"{w}: needle tip ({combo[3]:g} mm off axis)")
        ax.set_aspect("equal")
        ax.set_xlabel("x in the start gripper frame (mm)")
        ax.set_ylabel("y in the start gripper frame (mm)")
        ax.set_title(f"tracked path ({combo[2]})", fontsize=9)
        ax.legend(fontsize=7)
        paths.append(_save(fig, out / f"suture_path_{n_combo}.png"))
    return paths
