"""port-place figures: the layout in 3-D on the patient, the port region unrolled (top view) with every
candidate site coloured by the best feasible design that uses it, and why designs are infeasible."""
from __future__ import annotations

import numpy as np

from surgopt.robots.dvrk.platforms import PLATFORMS, role_of

from surgopt.studies.plotting import columns, pyplot, save
from surgopt.studies.port_place.carts import has_cart
from surgopt.studies.port_place.geometry import X_LABEL, Y_LABEL, Z_LABEL

COLOURS = {"psm1": "C3", "psm2": "C1", "psm3": "C2", "ecm": "C0"}


def arms(c: dict) -> list[tuple[str, str, str]]:
    """(column prefix, colour, label) of each arm in the rows: PSM1, PSM2, PSM3 when there is one, the ECM."""
    return [(arm, colour, role_of(arm)) for arm, colour in COLOURS.items() if f"{arm}_site" in c]


def target_top_view(ax, cfg, targets: np.ndarray, colour: str) -> None:
    """The target from above: its outline (sphere, ellipsoid, box), or its points when it came from a file or a
    mesh."""
    if cfg.target.shape in ("points", "mesh"):
        ax.scatter(targets[:, 0], targets[:, 1], s=4, color=colour, alpha=0.5, label="target points (top view)")
        return
    t = np.linspace(0, 2 * np.pi, 200)
    (rx, ry), (cx, cy) = cfg.target.radii_mm[:2], cfg.target.centre_mm[:2]
    if cfg.target.shape == "box":
        ax.fill(cx + rx * np.array([-1, 1, 1, -1]), cy + ry * np.array([-1, -1, 1, 1]), color=colour, alpha=0.25,
                label="target (top view)")
    else:
        ax.fill(cx + rx * np.cos(t), cy + ry * np.sin(t), color=colour, alpha=0.25, label="target (top view)")


def best_per_site(c: dict, n_sites: int) -> np.ndarray:
    """The least cost of a feasible design that puts any arm at each site (NaN where none does)."""
    out = np.full(n_sites, np.inf)
    ok = c["feasible"]
    for arm, _, _ in arms(c):
        np.minimum.at(out, c[f"{arm}_site"][ok], c["cost"][ok])
    out[~np.isfinite(out)] = np.nan
    return out


def chosen(c: dict, design_id: int | None, cfg=None) -> int | None:
    """The row of ``design_id``, or of the closing report's answer: the best feasible design (by cost, then
    design_id; ``cfg`` is accepted for the callers' sake: the answer never depends on a screen)."""
    if design_id is not None:
        rows = np.flatnonzero(c["design_id"] == design_id)
        return int(rows[0]) if len(rows) else None
    ok = np.flatnonzero(c["feasible"])
    return int(ok[np.lexsort((c["design_id"][ok], c["cost"][ok]))[0]]) if len(ok) else None


def cheapest_clash(c: dict) -> int | None:
    """The cheapest row (then the lowest design_id) that docks and fails on its links alone (reason 16), or None:
    with no layout to draw, the cart figure shows where the cheapest overlaps."""
    from surgopt.kinematics.port.reasons import OUTSIDE

    cand = np.flatnonzero((c["infeasible"] == OUTSIDE) & (c["cart_pose"] >= 0)) if "cart_pose" in c else []
    return int(cand[np.lexsort((c["design_id"][cand], c["cost"][cand]))[0]]) if len(cand) else None


def row_of(c: dict, r: int) -> dict:
    """Row ``r`` of the columns ``c`` as a dict of Python values."""
    return {k: (v[r].item() if hasattr(v[r], "item") else v[r]) for k, v in c.items()}


def held_arms(ax, model, sites_m: np.ndarray, ports: list) -> bool:
    """Each arm that holds its tool by its own joints (a serial arm: ``arms.SerialInstruments`` /
    ``SerialCamera``) drawn as its centre line (base, joints, flange, port) at its docked pose, at the (site,
    colour) ``ports`` (the instruments', then the camera's); whether any was drawn."""
    from surgopt.studies.port_place.config import camera_arm_of, instrument_of

    cfg = model.cfg
    drawn = False
    for holder, chosen, label in ((model.instruments, ports[:-1], f"{instrument_of(cfg).name}: base, joints, "
                                                                   "flange, port"),
                                  (model.endoscope, ports[-1:], f"{camera_arm_of(cfg).name} holding the endoscope")):
        lines = holder.docked_lines(model, sites_m[[site for site, _ in chosen]])
        if lines is None:
            continue
        for line, (_, colour) in zip(lines * 1000, chosen):
            ax.plot(*line.T, color=colour, lw=3, marker="o", ms=3, alpha=0.8)
        ax.plot([], [], color="0.3" if len(chosen) > 1 else chosen[0][1], lw=3, marker="o", ms=3, label=label)
        drawn = True
    return drawn


def figures(cfg, table, out, design_id=None):
    from surgopt.studies.port_place.model import model_of
    from surgopt.studies.port_place.rolls import first_docking, model_for

    plt = pyplot()
    c = columns(table)
    row = chosen(c, design_id, cfg)
    # the drawn layout's roll's tables (with rolls enumerated; the sites are every roll's)
    model = model_of(first_docking(cfg)) if row is None else model_for(cfg, row_of(c, row))
    sites_m, (port_tables, _, dex) = model.sites_m, model.grid
    sites = sites_m * 1000
    targets = model.targets_m * 1000
    per_site = best_per_site(c, len(sites))
    paths = []

    # 3-D: the dome, the candidate sites, the chosen ports with their shafts, the target by dexterity
    fig = plt.figure(figsize=(7.6, 6.2))
    ax = fig.add_subplot(projection="3d")
    from surgopt.studies.port_place.geometry import body_extent_mm, patient_mesh

    a, b, h = body_extent_mm(cfg.patient)
    if cfg.patient.shape == "dome":
        from surgopt.studies.port_place.geometry import dome_surface_mm

        u, v = np.meshgrid(np.linspace(0, 2 * np.pi, 49), np.linspace(0, np.pi / 2, 13))
        ax.plot_wireframe(*dome_surface_mm((a, b, h), cfg.patient.dome_exponent, u, v), color="0.8", lw=0.4)
    else:  # the mesh's triangles, thinned to at most ~4,000 for a readable figure
        mesh = patient_mesh(cfg.patient)
        faces = mesh.faces[:: max(1, len(mesh.faces) // 4000)]
        ax.plot_trisurf(*mesh.vertices.T, triangles=faces, color="0.85", alpha=0.25, lw=0.1, edgecolor="0.7")
    sc = ax.scatter(*sites.T, c=per_site, cmap="viridis_r", s=14, depthshade=False)
    fig.colorbar(sc, ax=ax, shrink=0.6, pad=0.1, label="least cost of a feasible design using the site")
    serial = False  # whether a serial arm is drawn (the view then from the feet, the box to the arms)
    if row is not None:
        from surgopt.studies.port_place.layout import layout_isotropy
        from surgopt.studies.port_place.designs import searched_docking

        iso = (layout_isotropy(model, row_of(c, row)) if searched_docking(cfg)  # the trial's own docking
               else np.min([dex[c[f"{arm}_site"][row]] for arm, _, _ in arms(c)[:-1]], axis=0))  # the instruments
        tp = ax.scatter(*targets.T, c=iso, cmap="magma", s=3, depthshade=False)
        # a palette and a colour bar of their own: the points' isotropy is not the sites' cost (#42 item 7)
        fig.colorbar(tp, ax=ax, shrink=0.6, pad=0.02, label="target point: the instruments' smaller isotropy")
        centre = np.asarray(cfg.target.centre_mm)
        for arm, colour, label in arms(c):
            p = sites[c[f"{arm}_site"][row]]
            ax.plot(*np.stack([p, centre]).T, color=colour, lw=2)
            ax.scatter(*p, color=colour, s=60, label=f"{label} site {c[f'{arm}_site'][row]}")
        # the report's answer (the best feasible row, ``chosen``), or the design asked for by its id, as its row says
        ax.set_title(f"port-place: design {c['design_id'][row]} (cost {c['cost'][row]:.3f}); target "
                     f"points by the smaller isotropy", fontsize=9)
        serial = held_arms(ax, model, sites_m, [(c[f"{arm}_site"][row], colour) for arm, colour, _ in arms(c)])
        ax.legend(fontsize=8, loc="upper left")
    ax.set_xlabel(X_LABEL)
    ax.set_ylabel(Y_LABEL)
    ax.set_zlabel(Z_LABEL)
    lims = [ax.get_xlim3d(), ax.get_ylim3d(), ax.get_zlim3d()]
    ax.set_box_aspect([hi - lo for lo, hi in lims] if serial else (a, b, h))
    ax.view_init(elev=28, azim=-100 if serial else -120)  # serial arms: from the feet
    paths.append(save(fig, out / "port_place_layout_3d.png"))

    # 2-D: the port region from above
    fig, ax = plt.subplots(figsize=(6.0, 6.4))
    t = np.linspace(0, 2 * np.pi, 200)
    if cfg.patient.shape == "dome":
        ax.plot(a * np.cos(t), b * np.sin(t), color="0.6", lw=1, label="dome base")
    else:
        ax.plot([-a, a, a, -a, -a], [-b, -b, b, b, -b], color="0.6", lw=1, label="mesh extent")
    target_top_view(ax, cfg, targets, "C4")
    sc = ax.scatter(sites[:, 0], sites[:, 1], c=per_site, cmap="viridis_r", s=40)
    none = np.isnan(per_site)
    ax.scatter(sites[none, 0], sites[none, 1], facecolors="none", edgecolors="0.5", s=40,
               label="no feasible design uses it")
    fig.colorbar(sc, ax=ax, shrink=0.8, label="least cost of a feasible design using the site")
    if row is not None:
        for arm, colour, label in arms(c):
            p = sites[c[f"{arm}_site"][row]]
            ax.plot(p[0], p[1], "*", color=colour, ms=16, mec="k", label=label)
    sides_and_landmarks(ax, cfg)
    ax.set_aspect("equal")
    ax.set_xlabel(X_LABEL)
    ax.set_ylabel(Y_LABEL)
    ax.set_title("candidate ports (top view) and the best layout", fontsize=9)
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=4)
    paths.append(save(fig, out / "port_place_sites_top.png"))

    paths.append(reach_maps(plt, cfg, sites, port_tables, dex, out))
    if has_cart(cfg) and row is not None and c["cart_pose"][row] >= 0:
        paths.append(cart_figure(plt, model, row_of(c, row), out))
    elif has_cart(cfg) and design_id is None and (clash := cheapest_clash(c)) is not None:
        drawn = row_of(c, clash)
        paths.append(cart_figure(plt, model_for(cfg, drawn), drawn, out, "no layout's links clear: the cheapest "
                                 "that fails on them alone"))

    # why designs fail
    from surgopt.kinematics.port.reasons import REASONS

    if cfg.rows_stored == "feasible":  # the infeasible designs' rows, and so their reasons, were not kept
        return paths
    fig, ax = plt.subplots(figsize=(7.0, 3.4))
    counts = [int(np.count_nonzero(c["infeasible"] & bit)) for bit in REASONS]
    ax.barh(range(len(REASONS)), counts, color="C7")
    ax.set_yticks(range(len(REASONS)), list(REASONS.values()), fontsize=7)
    ax.set_xlabel(f"designs (of {len(c['design_id']):,}; {int(c['feasible'].sum()):,} feasible)")
    ax.invert_yaxis()
    ax.set_title("why designs are infeasible (a design can fail several)", fontsize=9)
    paths.append(save(fig, out / "port_place_reasons.png"))
    return paths


def sides_and_landmarks(ax, cfg) -> None:
    """A top view's sides named (the patient's left and right, head and feet, at the axes' edges) and the
    patient's landmarks marked and labelled (``geometry.landmarks_mm``), the reference one in bold."""
    from surgopt.studies.port_place.geometry import landmarks_mm, reference_landmark

    ref, _ = reference_landmark(cfg.patient)
    for name, (x, y) in landmarks_mm(cfg.patient).items():
        ax.plot(x, y, "P", color="k", ms=7, mfc="w")
        ax.annotate(name, (x, y), xytext=(5, 4), textcoords="offset points", fontsize=7,
                    fontweight="bold" if name == ref else "normal")
    style = dict(transform=ax.transAxes, fontsize=8, color="0.3", ha="center", va="center")
    ax.text(0.98, 0.5, "L", **style)
    ax.text(0.02, 0.5, "R", **style)
    ax.text(0.5, 0.98, "head", **style)
    ax.text(0.5, 0.02, "feet", **style)


def reach_maps(plt, cfg, sites, t, dex, out):
    """Per-arm maps, top view: the share of the target an instrument docked at each site reaches (within its joint
    limits and any approach cone), its mean isotropy over the points it reaches, and the share of the target the
    camera docked there sees. A map whose value is the same at every site says so in its title."""
    from surgopt.studies.port_place.geometry import body_extent_mm, target_points_mm

    a, b, _ = body_extent_mm(cfg.patient)
    reached = t.reach_count / t.n_points
    iso = np.where(t.reach_count > 0, t.dex_site, np.nan)
    maps = ((reached, "instrument: share of the target reached", (0.0, 1.0)),
            (iso, "instrument: mean isotropy there", (np.nanmin(iso), max(np.nanmax(iso), np.nanmin(iso) + 1e-3))),
            (t.coverage, "camera: share of the target seen", (0.0, 1.0)))
    fig, axes = plt.subplots(1, 3, figsize=(13.0, 4.6), sharey=True)
    targets = target_points_mm(cfg.target)
    for ax, (v, title, (vmin, vmax)) in zip(axes, maps):
        lo, hi = np.nanmin(v), np.nanmax(v)
        sc = ax.scatter(sites[:, 0], sites[:, 1], c=v, cmap="viridis", vmin=vmin, vmax=vmax, s=30)
        fig.colorbar(sc, ax=ax, shrink=0.75, pad=0.02)
        target_top_view(ax, cfg, targets, "C3")
        ax.set_xlim(-a, a)
        ax.set_ylim(-b, b)
        sides_and_landmarks(ax, cfg)
        ax.set_aspect("equal")
        ax.set_xlabel(X_LABEL)
        ax.set_title(title + (f"\n(every site: {lo:.2f})" if np.isclose(lo, hi) else f"\n({lo:.2f} to {hi:.2f})"),
                     fontsize=9)
    axes[0].set_ylabel(Y_LABEL)
    axes[0].legend(fontsize=7, loc="lower left")
    from surgopt.studies.port_place.config import camera_arm_of, instrument_of

    fig.suptitle(f"per-arm maps: {instrument_of(cfg).name} and {camera_arm_of(cfg).name} docked at each candidate "
                 f"site toward the target's centre", fontsize=9)
    return save(fig, out / "port_place_reach_top.png")


def cart_figure(plt, model, row: dict, out, note: str = ""):
    """The layout on the cart, in the cart's world frame (m; the floor at z = 0): the patient's surface and the
    table, each arm's setup joints as the polyline of their frames (base, each link, the SUJ's tip), the arm's
    own links docked (the axes of ``clashes``' capsules: mount, yaw link, parallelogram, insertion stage,
    housing, the shaft outside the port) and a line from the RCM in to the target's centre; docked as the dvrk
    export docks it (``clashes.docking_that_clears``: each PSM rolled about its shaft where that clears the links).
    Where its links overlap however docked, the two links of the least clearance are drawn red and named;
    ``note``: why this layout is drawn, when it is not the best."""
    from surgopt.studies.port_place.geometry import body_extent_mm, dome_surface_mm
    from surgopt.studies.port_place.clashes import arm_poses
    from surgopt.studies.port_place.layout import layout_of, setup_joint_frames

    cfg = model.cfg
    layout = layout_of(model, row)  # as the dvrk export docks it
    patient = layout.patient_in_cart
    to_cart = lambda p: p @ patient[:3, :3].T + patient[:3, 3]  # noqa: E731 - patient (m) -> cart world (m)
    fig = plt.figure(figsize=(8.0, 6.6))
    ax = fig.add_subplot(projection="3d")
    a, b, h = body_extent_mm(cfg.patient)
    if cfg.patient.shape == "dome":
        u, v = np.meshgrid(np.linspace(0, 2 * np.pi, 37), np.linspace(0, np.pi / 2, 10))
        x, y, z = dome_surface_mm((a, b, h), cfg.patient.dome_exponent, u, v)
        pts = to_cart(np.stack([x, y, z], -1).reshape(-1, 3) / 1000).reshape(x.shape + (3,))
        ax.plot_wireframe(pts[..., 0], pts[..., 1], pts[..., 2], color="0.75", lw=0.4)
    from surgopt.studies.port_place.bedside import bedside_boxes, box_edges

    for k, box in enumerate(bedside_boxes(cfg)):  # the table's slab, its rails, the patient's arms and legs
        for e, edge in enumerate(box_edges(box.lo, box.hi)):
            label = None if e else "table" if k == 0 else "the bedside: rails, the patient's arms, legs" if k == 1 else None
            ax.plot(*to_cart(edge).T, color="0.5" if k == 0 else "tab:brown", lw=0.8, label=label)
    (fx0, fy0), (fx1, fy1) = PLATFORMS[cfg.cart.model].footprint_m  # the cart's base on the floor, its world frame
    floor_z = -PLATFORMS[cfg.cart.model].world_above_floor_m
    ax.plot([fx0, fx1, fx1, fx0, fx0], [fy0, fy0, fy1, fy1, fy0], [floor_z] * 5, color="0.25", lw=1.2,
            label=f"cart's base on the floor (its mesh's; >= {cfg.cart.clear_of_table_mm:g} mm from the table)")
    centre = to_cart(np.asarray(cfg.target.centre_mm, float) / 1000)
    ax.scatter(*centre, color="k", s=20, label="target centre")
    docked, rolls, clearances = layout.docked, layout.rolls, layout.clearances
    from surgopt.studies.port_place.clashes import least, turn_words

    worst = least(clearances)
    overlap = worst if worst is not None and worst.clearance_mm < 0 else None

    turned = ", ".join(f"{a} {turn_words(cfg)[1]} {d:+.0f} deg" for a, d in rolls.items() if d)
    for arm, colour in zip(docked, ("C0", "C1", "C2", "C3")):
        if not arm.joints:
            continue
        f = setup_joint_frames(cfg, arm)
        ax.plot(*f[:-1, :3, 3].T, color=colour, lw=2.5, marker="o", ms=3, label=f"{arm.arm} setup joints")
        links = arm_poses(model, arm, patient, model.targets_m[:0])  # in the patient's frame: drawn in the cart's
        own = [i for i, n in enumerate(links.names) if "setup joint" not in n]
        for k, i in enumerate(own):  # the arm's own links, docked (clashes.py's capsules)
            ax.plot(*to_cart(links.segments[0, i]).T, color=colour, lw=1.2, alpha=0.8,
                    label=f"{arm.arm} links (capsule axes)" if k == 0 else None)
        ax.plot(*np.stack([f[-1, :3, 3], centre]).T, color=colour, lw=0.8, ls="--")
        for i, n in enumerate(links.names):  # the overlapping pair, docked (it may overlap at another pose)
            if overlap is not None and n in (overlap.link_a, overlap.link_b):
                ax.plot(*to_cart(links.segments[0, i]).T, color="red", lw=4, alpha=0.7,
                        label="the overlapping links (docked)" if n == overlap.link_a else None)

    above = PLATFORMS[cfg.cart.model].world_above_floor_m
    ax.plot([0], [0], [0], "ks", ms=8, label="cart origin" + (f" ({above:.2f} m above the floor: chosen)" if above
                                                               else " (on the floor)"))
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y, the cart's forward (m)")
    ax.set_zlabel("z up (m)")
    lims = np.array([ax.get_xlim3d(), ax.get_ylim3d(), ax.get_zlim3d()])
    ax.set_box_aspect(lims[:, 1] - lims[:, 0])
    ax.view_init(elev=22, azim=-60)
    ax.set_title(f"design {row['design_id']} on the {PLATFORMS[cfg.cart.model].title} cart: origin ({row['cart_x_mm']:.0f}, "
                 f"{row['cart_y_mm']:.0f}) mm, heading {row['cart_heading_deg']:.0f} deg (patient frame)"
                 + (f"\ndocked as the dvrk export docks it so that the links clear: {turned}" if turned else "")
                 + (f"\n{note}" if note else "")
                 + (f"\nits links overlap however docked: {overlap.link_a} / {overlap.link_b} by "
                    f"{-overlap.clearance_mm:.0f} mm\n({overlap.where})" if overlap is not None else ""),
                 fontsize=9)
    ax.legend(fontsize=7, loc="upper left")
    return save(fig, out / "port_place_cart_3d.png")
