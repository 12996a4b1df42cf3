"""Organs as obstacles (issue 57 item 1): an instrument's shaft must not cross an organ on its way to a target point.

An organ is a closed triangle mesh in the patient's frame (``patient.organs``: read with the patient mesh's units
and offset, since a CT's organs share its frame, as OpenHELP's do). It is taken as its voxels, ``ORGAN_PITCH_MM``
on a side: trimesh's surface voxels (every voxel the surface passes through) with the inside filled, so the
obstacle holds the whole organ and reaches at most one voxel's diagonal (3.5 mm) past its surface, never less: a
conservative obstacle (a shaft grazing an organ within that band counts as crossing it).

A shaft runs from its port to the target point its tip reaches (the instrument's shaft and wrist, taken as one
segment). It crosses an organ when one of its points sampled every half voxel (the segment cut into equal steps no
longer than ``ORGAN_PITCH_MM / 2``, each step's middle) lies in one of the organ's voxels, farther from the target
point than the voxels reach past a surface (``ORGAN_REACH_MM``): organs touch the target (the stomach lies on the
pancreas), and the tip works there, so an organ within that reach of the point is not one the shaft crosses on its
way. The port lies on the skin and no target point lies inside an obstacle's own mesh (a config whose target does is
refused, naming the organ).

What this leaves out: the organs do not move (no retraction, no insufflation of the bowel), the camera's line of
sight and the scope's shaft are not checked against them, and the links outside the body never meet them.
"""
from __future__ import annotations

from functools import lru_cache
from typing import NamedTuple

import numpy as np

#: The side of an organ's voxels (mm): the obstacle reaches at most sqrt(3) of it past the organ's surface.
ORGAN_PITCH_MM = 2.0
#: How far the voxels reach past an organ's surface at most (a voxel's diagonal, mm): the last stretch of a shaft,
#: this close to its target point, is not checked (the module's rule).
ORGAN_REACH_MM = float(np.sqrt(3) * ORGAN_PITCH_MM)


class OrganGrid(NamedTuple):
    """One organ as voxels: ``filled[i, j, k]`` is the voxel centred at ``origin_mm + (i, j, k) * pitch_mm``."""

    name: str
    filled: np.ndarray
    origin_mm: np.ndarray
    pitch_mm: float


@lru_cache(maxsize=32)
def organ_grid(name: str, path: str, sha256: str, units: str, offset_mm: tuple) -> OrganGrid:
    """The organ's mesh (``geometry.body_mesh``: read, checked closed, in mm, offset) as filled voxels, once per
    file content."""
    from surgopt.studies.port_place.geometry import body_mesh

    mesh = body_mesh(path, sha256, units, offset_mm)
    voxels = mesh.voxelized(pitch=ORGAN_PITCH_MM).fill()
    transform = np.asarray(voxels.transform, float)
    return OrganGrid(name, np.asarray(voxels.matrix, bool), transform[:3, 3].copy(), float(transform[0, 0]))


def organ_grids(patient) -> list[OrganGrid]:
    """Every obstacle of ``patient.organs`` (``obstacle = true``) as voxels, by name in the config's order ([]
    without any)."""
    return [organ_grid(name, organ.mesh_file, organ.mesh_sha256, patient.mesh_units, tuple(patient.mesh_offset_mm))
            for name, organ in (patient.organs or {}).items() if organ.obstacle]


def organ_at(points_mm: np.ndarray, grids: list[OrganGrid]) -> np.ndarray:
    """(...,) int: the index (in ``grids``) of the first organ whose voxels hold each point (mm), -1 for none."""
    points = np.asarray(points_mm, float)
    out = np.full(points.shape[:-1], -1, np.int64)
    for g, grid in enumerate(grids):
        idx = np.rint((points - grid.origin_mm) / grid.pitch_mm).astype(np.int64)
        ok = np.all((idx >= 0) & (idx < np.array(grid.filled.shape)), axis=-1) & (out < 0)
        hit = np.zeros(points.shape[:-1], bool)
        hit[ok] = grid.filled[idx[ok, 0], idx[ok, 1], idx[ok, 2]]
        out[hit] = g
    return out


def shafts_crossing(sites_m: np.ndarray, targets_m: np.ndarray, grids: list[OrganGrid]) -> np.ndarray:
    """[site, point] int: the organ (index in ``grids``) the straight shaft from the site to the target point
    crosses first along it (the module's rule), -1 where it crosses none."""
    sites, targets = np.asarray(sites_m, float) * 1000, np.asarray(targets_m, float) * 1000
    out = np.full((len(sites), len(targets)), -1, np.int64)
    if not grids or not len(sites) or not len(targets):
        return out
    step = min(g.pitch_mm for g in grids) / 2
    for i, site in enumerate(sites):
        d = targets - site
        length = np.linalg.norm(d, axis=1)
        k = max(2, int(np.ceil(length.max() / step)))
        t = (np.arange(k) + 0.5) / k  # each step's middle, port to point
        at = organ_at(site + t[None, :, None] * d[:, None, :], grids)  # (points, k)
        crossed = (at >= 0) & ((1.0 - t[None, :]) * length[:, None] > ORGAN_REACH_MM)  # on the way, not at the tip
        first = np.argmax(crossed, axis=1)
        out[i] = np.where(crossed.any(axis=1), at[np.arange(len(targets)), first], -1)
    return out


def shafts_clear(model, sites_m: np.ndarray) -> np.ndarray | None:
    """[site, point] bool: the shaft from each site to each of the model's target points crosses no organ; None
    when the patient has no organs (nothing to mask). The model's own candidate sites are computed once
    (``PortModel.organ_crossing``)."""
    grids = organ_grids(model.cfg.patient)
    if not grids:
        return None
    return shafts_crossing(sites_m, model.targets_m, grids) < 0


def organs_words(model) -> str:
    """The closing report's line: which organs the shafts clear, by the module's rule, and how many of the shafts
    from the candidate sites to the target's points cross each (so are out of reach)."""
    grids = organ_grids(model.cfg.patient)
    crossing = model.organ_crossing  # the reach tables' own, once per model
    each = ", ".join(f"{g.name} {int(np.count_nonzero(crossing == k)):,}" for k, g in enumerate(grids))
    return (f"no instrument's shaft crosses {', '.join(g.name for g in grids)} on its way to the target (each taken "
            f"as its {ORGAN_PITCH_MM:g} mm voxels, at most {ORGAN_REACH_MM:.1f} mm past its surface, up to that far from "
            f"the tip); of "
            f"the {crossing.size:,} shafts from the candidate sites to the target's points, these cross one and are "
            f"out of reach: {each}. The organs do not move (no retraction)")


def clear_reach(model, sites_m: np.ndarray, reach: np.ndarray, dex: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(reach, isotropy) with every (site, point) whose shaft crosses an organ taken out of reach (its isotropy
    0, as for any point not reached): the one place organs enter the instruments' tables."""
    clear = (model.shafts_clear_at_sites if sites_m is model.sites_m else shafts_clear(model, sites_m))
    if clear is None:
        return reach, dex
    reach = np.asarray(reach, bool) & clear
    return reach, np.where(reach, dex, 0.0)
