"""Organs as obstacles (issue 57 item 1): the shafts that cross an organ, by the voxel rule, against trimesh's own
ray-triangle test on the organs' meshes, on OpenHELP's distal pancreatectomy.

Run:  python benchmarks/bench_organs.py      (needs ../shared/patients/openhelp beside the checkout)
Prints:
- building the organs' voxels (``organs.organ_grid``, once per file in a process);
- ``organs.shafts_crossing`` over every (candidate site, target point) shaft: shafts/s;
- the same shafts against each obstacle's mesh by trimesh's ray test (``ray.intersects_location``: the first hit of
  the ray from the port toward the point, nearer than the point less the rule's tip reach), shafts/s, and the
  same-run ratio;
- how often the two agree, and where they differ how far the shaft passes from the organ's surface (the voxel
  rule reaches at most ``ORGAN_REACH_MM`` past a surface: its only disagreements should lie within that).
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from surgopt.compose import variants
from surgopt.studies import get_study
from surgopt.studies.port_place import organs as O
from surgopt.studies.port_place.geometry import body_mesh
from surgopt.studies.port_place.model import prepare

HERE = Path(__file__).resolve().parents[1]


def main() -> None:
    study = get_study("port-place")
    (v,) = variants(study, [HERE / "configs" / "patients" / "openhelp.toml",
                            HERE / "configs" / "openhelp_distal_pancreatectomy.toml"], [])
    cfg = v.config
    model = prepare(cfg)
    t0 = time.perf_counter()
    grids = O.organ_grids(cfg.patient)
    built = time.perf_counter() - t0
    sites, targets = model.sites_m, model.targets_m
    n = len(sites) * len(targets)
    print(f"OpenHELP distal pancreatectomy: {len(grids)} obstacles, {len(sites)} sites x {len(targets)} target points "
          f"= {n:,} shafts")
    print(f"voxels ({O.ORGAN_PITCH_MM:g} mm) built in {built:.2f} s")
    t0 = time.perf_counter()
    crossing = O.shafts_crossing(sites, targets, grids)
    voxel_s = time.perf_counter() - t0
    print(f"shafts_crossing (voxels): {voxel_s:.3f} s, {n / voxel_s:,.0f} shafts/s; {int((crossing >= 0).sum()):,} cross")

    p = cfg.patient
    meshes = [body_mesh(o.mesh_file, o.mesh_sha256, p.mesh_units, tuple(p.mesh_offset_mm))
              for o in p.organs.values() if o.obstacle]
    origins = np.repeat(sites * 1000, len(targets), axis=0)
    ends = np.tile(targets * 1000, (len(sites), 1))
    d = ends - origins
    length = np.linalg.norm(d, axis=1)
    t0 = time.perf_counter()
    hit = np.zeros(n, bool)
    for mesh in meshes:
        loc, ray, _ = mesh.ray.intersects_location(origins, d / length[:, None], multiple_hits=False)
        near = np.linalg.norm(loc - origins[ray], axis=1) < length[ray] - O.ORGAN_REACH_MM
        hit[ray[near]] = True
    ray_s = time.perf_counter() - t0
    print(f"trimesh's ray test: {ray_s:.3f} s, {n / ray_s:,.0f} shafts/s; {int(hit.sum()):,} cross; voxels "
          f"{ray_s / voxel_s:.1f}x its speed (same run)")
    voxel = (crossing >= 0).ravel()
    agree = float((voxel == hit).mean())
    print(f"agreement: {agree:.4f} of the shafts ({int((voxel & ~hit).sum()):,} crossing by the voxels only, "
          f"{int((hit & ~voxel).sum()):,} by the rays only)")
    differ = np.flatnonzero(voxel != hit)
    if len(differ):  # how near the organs those shafts pass: the voxels reach at most ORGAN_REACH_MM past a surface
        from trimesh.proximity import closest_point

        pts = origins[differ][:, None, :] + np.linspace(0.02, 0.98, 60)[None, :, None] * d[differ][:, None, :]
        least = np.full(len(differ), np.inf)
        for mesh in meshes:
            _, dist, _ = closest_point(mesh, pts.reshape(-1, 3))
            least = np.minimum(least, dist.reshape(len(differ), -1).min(axis=1))
        print(f"where they differ, the shaft passes {least.min():.2f}-{least.max():.2f} mm from an organ's surface "
              f"(the voxels' reach: {O.ORGAN_REACH_MM:.2f} mm)")


if __name__ == "__main__":
    main()
