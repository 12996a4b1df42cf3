"""Draw a port-place layout's two PSMs with their own meshes and fitted capsules at the pose pair where their
links come closest (issue 54: "if the Si still never clears, show why with the meshes drawn").

    python tools/draw_link_meshes.py OUT.png DESIGN_ID [override ...]
    python tools/draw_link_meshes.py docs/figures/port_place_si_links_meshes.png 1499591 \
        cart.model=si robot.instrument_arm=dvrk_psm_si robot.camera_arm=dvrk_ecm_si

runs (or reads from a temporary store) the default port-place study with the overrides, docks the design's row as
the report does (``tables.docked_arms``), finds the pair of poses (each PSM docked or at a target point) of least
clearance (``clashes.between``), and draws both arms' meshes (jhu-dvrk/dvrk_model at the commit the envelopes were
fitted from, placed by surgopt's skeleton) with their capsules' axes, in three views of the cart's world frame.
Needs the dVRK model repository (``fetch github:jhu-dvrk/dvrk_model``) at MIRROR.
"""
from __future__ import annotations

import io
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
import fit_link_envelopes as F  # noqa: E402

MIRROR = "/work/.mirror/jhu-dvrk+dvrk_model/repo"


def main(out: str, design_id: int, overrides: list[str]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import trimesh

    import surgopt
    from surgopt.config import load_embedded
    from surgopt.kinematics.port import capsules as C
    from surgopt.kinematics.port import suj as S
    from surgopt.kinematics.port.place import rcm_inverse
    from surgopt.robots.dvrk import link_envelopes as E
    from surgopt.robots.dvrk.platforms import PLATFORMS
    from surgopt.studies import get_study
    from surgopt.studies.port_place.clashes import arm_poses, between
    from surgopt.studies.port_place.link_tables import pose_points
    from surgopt.studies.port_place.model import model_of
    from surgopt.studies.port_place.tables import docked_arms, row_patient_in_cart

    df = surgopt.run("port-place", overrides=overrides, store=Path(tempfile.gettempdir()) / "surgopt-draw-store")
    row = df[df.design_id == design_id].iloc[0].to_dict()
    study = get_study("port-place")
    from surgopt.compose import variants

    cfg = variants(study, None, overrides)[0].config if overrides else load_embedded(study.default_config,
                                                                                       study.config_model)
    model = model_of(cfg)
    patient = row_patient_in_cart(cfg, row)
    points = pose_points(model)[0]
    arms = [a for a in docked_arms(model, row) if a.arm.startswith("PSM") and a.joints]
    poses = [arm_poses(model, a, patient, points) for a in arms]
    _, moving = between(poses[0], poses[1])
    psm_capsules = PLATFORMS[cfg.cart.model].own_links(arms[0].arm)[1]  # the platform's PSM links: which meshes
    skeleton_name = next(e.skeleton for e in E.ENVELOPES if any(e.mesh in c.source for c in psm_capsules))
    fig, axes = plt.subplots(1, 3, figsize=(16, 6))
    views = ((0, 1, "top (x, y)"), (0, 2, "front (x, z)"), (1, 2, "side (y, z)"))
    for arm, armp, colour in zip(arms, poses, ("C0", "C1")):
        label = moving.where.split("; ")[0 if arm.arm == arms[0].arm else 1].removeprefix(f"{arm.arm} ")
        k = armp.poses.index(label)
        base = arm.base
        if k == 0:
            centre = np.asarray(cfg.target.centre_mm, float) / 1000 @ patient[:3, :3].T + patient[:3, 3]
            q = (0.0, 0.0, float(np.linalg.norm(centre - base[:3, 3])) - model.limits.along_shaft_m)
        else:
            world = points[k - 1] @ patient[:3, :3].T + patient[:3, 3]
            q = rcm_inverse((world - base[:3, 3]) @ base[:3, :3], model.limits.along_shaft_m)
        mount = S.frames(PLATFORMS[cfg.cart.model].suj(arm.arm), arm.joints)[-2]
        frames_def, capsules = PLATFORMS[cfg.cart.model].own_links(arm.arm)
        frames = C.skeleton(frames_def, np.asarray(q, float), base, mount)
        for sk, frame, name, path, xyz, rpy, _ in F.LINKS:
            if sk != skeleton_name:
                continue
            mesh = trimesh.load(io.BytesIO(F.mesh_bytes(MIRROR, path)), file_type=Path(path).suffix[1:].lower(),
                                force="mesh")
            v = mesh.vertices @ F.rpy_matrix(rpy).T + np.asarray(xyz)
            w = v @ frames[frame][:3, :3].T + frames[frame][:3, 3]
            for ax, (i, j, _) in zip(axes, views):
                ax.scatter(w[:, i], w[:, j], s=0.2, color=colour, alpha=0.35)
        caps = C.capsules_at(capsules, frames)
        for n, seg, r in zip(caps.names, caps.segments, caps.radii):
            red = f"{arm.arm} {n}" in (moving.link_a, moving.link_b)
            for ax, (i, j, _) in zip(axes, views):
                ax.plot(seg[:, i], seg[:, j], color="red" if red else colour, lw=2.5 if red else 0.8)
                if red:
                    for p in seg:
                        ax.add_patch(plt.Circle((p[i], p[j]), r, fill=False, color="red", lw=0.8))
        for ax, (i, j, _) in zip(axes, views):
            ax.plot(base[i, 3], base[j, 3], "k+", ms=10)
    for ax, (i, j, title) in zip(axes, views):
        ax.set_aspect("equal")
        ax.set_title(title, fontsize=9)
        ax.set_xlabel(f"{'xyz'[i]} (m, cart world)")
        ax.set_ylabel(f"{'xyz'[j]} (m)")
    fig.suptitle(f"design {design_id} ({', '.join(overrides) or 'the default'}): {arms[0].arm} (blue) and "
                 f"{arms[1].arm} (orange) as the dVRK's meshes (points) and their fitted capsules (axes), at the poses "
                 f"of least clearance\n{moving.link_a} / {moving.link_b}: {moving.clearance_mm:.0f} mm "
                 f"({moving.where}); red: the two capsules (circles: their radius at the ends); +: each RCM",
                 fontsize=9)
    fig.tight_layout()
    fig.savefig(out, dpi=90)
    print(out, moving)


if __name__ == "__main__":
    main(sys.argv[1], int(sys.argv[2]), sys.argv[3:])
