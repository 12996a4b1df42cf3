"""Study ``port-place``: where the ports go for a multi-arm RCM robot on a patient (dVRK: two PSMs + the ECM).

Beyond the three papers (issue #29; ../shared/robots/dvrk-kinematics.md). A design is one port for each
instrument arm and one for the camera arm, each chosen from candidate sites sampled on the insufflated
abdominal wall; each arm is docked with its neutral shaft through the target's centre. Per design: each
instrument's reach of the target (RCM inverse kinematics within the joint limits), the common reach, the
instruments' dexterity (isotropy with a stated characteristic length), the manipulation angle between
them (Hanna et al. 1997: 45-75 deg, 60 best), the azimuth imbalance about the optical axis, the camera's
coverage of the target, the port spacing and the shafts' clearance inside and the arms' outside, a cost
and the reasons a design is infeasible. Every assignment of two instrument ports (unordered: the PSMs are
the same arm) and a distinct camera port is evaluated; docs/port_placement.md has the model, its sources
and assumptions.

One module of ~420 lines: the study's config, the geometry it implies (patient, sites, target),
the memoised tables, the rows and the summary are one declaration, read together.
"""
from __future__ import annotations

import math
from functools import lru_cache
from typing import Literal

import numpy as np
from pydantic import Field, ValidationInfo, model_validator

from surgopt.config import NOT_IN_KEY, StrictModel
from surgopt.robots import dvrk
from surgopt.studies import Estimate, Study, Summary, figures_in, peak_bytes
from surgopt.studies.search import check_objectives, search_field

NAME = "port-place"
KERNEL_VERSION = "port-place-1"
DEFAULT_CONFIG = "port_place_dvrk.toml"
HELP = """Port placement for the da Vinci Research Kit on a patient: two PSMs and the ECM (issue #29).

    Candidate ports on an insufflated abdomen (a half-ellipsoid dome), a target inside it (sphere, ellipsoid
    or box sampled at a spacing). Every assignment of the two instrument ports and the camera port is one
    design: reach of each instrument (closed-form RCM inverse kinematics within the joint limits), common
    reach, dexterity, manipulation angle (45-75 deg, Hanna 1997), azimuth imbalance, camera coverage, port
    spacing, shaft and arm clearances, cost, and why a design is infeasible (a bit mask). Rows: one per
    design. The summary ranks feasible designs by cost and checks the best against the clinical numbers."""
CONFIG_HELP = "TOML or YAML config ([patient], [target], [robot], [constraints], [objective]); default: the dVRK example."

Vec3 = list[float]
#: What summarize and a search rank by (higher is better): -cost, less 100 per reason a design fails.
OBJECTIVE = "score"
#: Columns a [search] may optimise.
SEARCH_OBJECTIVES = ("score", "cost", "common_reach", "dexterity_mean", "camera_coverage", "shaft_clearance_mm",
                     "external_clearance_mm", "azimuth_imbalance_deg", "manipulation_angle_share_45_75")


class PortRegion(StrictModel):
    """Where on the wall ports may go: sites on a grid of ``site_spacing_mm`` in the top view, on the dome where
    its height is at least ``min_height_fraction`` of the top (the flanks are too steep to dock)."""

    site_spacing_mm: float = Field(18.0, ge=5.0, le=200.0)
    min_height_fraction: float = Field(0.45, ge=0.0, lt=1.0)


class Patient(StrictModel):
    """The insufflated abdomen: a half-ellipsoid dome over the plane z = 0 (x lateral, patient's left +x; y
    toward the head; z anterior), semi-axes in mm. Default 170 x 210 x 140 mm: an assumption (an adult
    abdomen ~34 cm wide and ~42 cm long; insufflation raises the wall ~6 cm, J Endourol 18(6):572, 2004)."""

    shape: Literal["dome", "mesh"] = Field("dome", description="'dome' (semi_axes_mm) or 'mesh' (mesh_file)")
    semi_axes_mm: Vec3 = Field([170.0, 210.0, 140.0], min_length=3, max_length=3)
    mesh_file: str | None = Field(None, min_length=1, description="a closed triangle mesh of the insufflated body "
                                  "(STL, OBJ or PLY, read by trimesh), relative to the config file (its content "
                                  "hash, mesh_sha256, is in the store key, not its path)",
                                  json_schema_extra=NOT_IN_KEY)
    mesh_units: Literal["mm", "m"] = Field("mm", description="the mesh file's length unit")
    mesh_offset_mm: Vec3 = Field([0.0, 0.0, 0.0], min_length=3, max_length=3,
                                 description="added to the mesh (after units): its base on z = 0, x lateral, y "
                                             "toward the head, z anterior, as for the dome")
    mesh_sha256: str | None = Field(None, description="filled in: the mesh file's content hash (in the store key)")
    port_region: PortRegion = PortRegion()

    @model_validator(mode="after")
    def _positive(self, info: ValidationInfo):
        if min(self.semi_axes_mm) <= 0:
            raise ValueError("semi_axes_mm: every semi-axis must be > 0")
        if self.shape == "mesh":
            self._resolve_mesh(info.context or {})
        elif self.mesh_file is not None:
            raise ValueError("mesh_file is given but shape is 'dome': set shape = 'mesh' to use it")
        return self

    def _resolve_mesh(self, context) -> None:
        """The mesh file, relative to the config's folder, read (bounded), hashed and checked closed."""
        import hashlib
        from pathlib import Path

        if self.mesh_file is None:
            raise ValueError("shape = 'mesh' needs mesh_file (an STL, OBJ or PLY file)")
        path = Path(self.mesh_file).expanduser()
        if not path.is_absolute():
            path = Path(context.get("config_dir") or Path.cwd()) / path
        path = path.resolve()
        object.__setattr__(self, "mesh_file", str(path))
        if context.get("stored"):
            return
        data = _read_mesh_bytes(path)
        sha = hashlib.sha256(data).hexdigest()
        if self.mesh_sha256 is not None and self.mesh_sha256 != sha:
            raise ValueError(f"mesh_file: {path} changed since this config was written (mesh_sha256 differs); drop "
                             f"mesh_sha256 to use the file as it is now")
        object.__setattr__(self, "mesh_sha256", sha)
        body_mesh(str(path), sha, self.mesh_units, tuple(self.mesh_offset_mm))  # parsed and checked once here


class Target(StrictModel):
    """The anatomy every instrument must reach: a sphere, ellipsoid or box (``radii_mm``: semi-axes, or half
    sides), sampled on a grid of ``spacing_mm``. Default: an ellipsoid of 35 x 45 x 30 mm semi-axes in the
    pelvis, 100 mm caudal of the dome's top and 40 mm above its base (a prostate-bed-like target; an
    assumption)."""

    shape: Literal["sphere", "ellipsoid", "box"] = "ellipsoid"
    centre_mm: Vec3 = Field([0.0, -100.0, 40.0], min_length=3, max_length=3)
    radii_mm: Vec3 = Field([35.0, 45.0, 30.0], min_length=3, max_length=3)
    spacing_mm: float = Field(6.0, ge=0.5, le=100.0)
    approach_direction: Vec3 | None = Field(
        None, min_length=3, max_length=3, description="the direction the jaws must point along at every target "
        "point (patient frame; e.g. [0, 0, -1]: straight down); none: any")
    approach_half_angle_deg: float = Field(
        0.0, ge=0.0, le=90.0, description="every direction within this angle of approach_direction must be "
        "reachable (the wrist bends the jaws up to its limit away from the shaft)")

    @model_validator(mode="after")
    def _positive(self):
        if min(self.radii_mm) <= 0:
            raise ValueError("radii_mm: every radius must be > 0")
        if self.approach_direction is not None:
            if math.hypot(*self.approach_direction) < 1e-9:
                raise ValueError("approach_direction: must be a direction, not [0, 0, 0]")
            bend = math.degrees(dvrk.LND_WRIST_BEND_RAD)
            if self.approach_half_angle_deg > bend:
                raise ValueError(f"approach_half_angle_deg: {self.approach_half_angle_deg:g} deg is more than the "
                                 f"instrument's wrist can bend the jaws from its shaft ({bend:.0f} deg): no port "
                                 f"can give every direction of that cone")
        elif self.approach_half_angle_deg:
            raise ValueError("approach_half_angle_deg goes with approach_direction")
        return self


class Robot(StrictModel):
    instrument_arm: Literal[tuple(dvrk.INSTRUMENT_ARMS)] = "dvrk_psm_classic"
    camera_arm: Literal[tuple(dvrk.CAMERA_ARMS)] = "dvrk_ecm_classic"
    camera_fov_deg: float = Field(70.0, gt=0, lt=180, description="full view angle of a 0-deg scope (60-70 typical)")
    camera_standoff_mm: float = Field(100.0, gt=0, description="the scope tip stops this far before the target centre")
    camera_range_mm: list[float] = Field([10.0, 200.0], min_length=2, max_length=2,
                                         description="sharp imaging range from the tip")
    docking_range_deg: float = Field(0.0, ge=0.0, le=60.0,
                                     description="a [search] may turn each PSM's base this far (yaw and pitch) off "
                                                 "the target's centre (free docking); 0: docked toward the centre. "
                                                 "The grid enumerates the default docking only")


class Constraints(StrictModel):
    min_port_spacing_mm: float = Field(80.0, ge=0, description="between any two ports (assumption: 8 cm)")
    port_to_target_mm: list[float] = Field([80.0, 180.0], min_length=2, max_length=2,
                                           description="candidate sites this far from the target centre "
                                                       "(<= 18 cm: J Endourol 18(6):572, 2004)")
    shaft_diameter_mm: float = Field(dvrk.INSTRUMENT_SHAFT_DIAMETER_MM, gt=0)
    min_shaft_clearance_mm: float = Field(5.0, ge=0, description="between shaft surfaces inside the body")
    tip_zone_mm: float = Field(30.0, ge=0, description="last stretch before the target centre left out of the "
                                                        "shafts' clearance (the instruments meet there)")
    min_external_clearance_mm: float = Field(60.0, ge=0, description="between arm axes outside the body, along "
                                                                     "the 0.4318 m behind each port")
    manipulation_angle_deg: list[float] = Field([45.0, 75.0], min_length=2, max_length=2)
    dexterity_length_m: float = Field(0.1, gt=0, description="characteristic length L of the isotropy")


class Objective(StrictModel):
    """Weights of the cost (minimised): unreached share, |mean manipulation angle - 60 deg| (rad), azimuth
    imbalance plus the optical axis's angle off the arc between the instruments (rad), unseen share,
    1 - mean isotropy."""

    reach: float = Field(10.0, ge=0)
    angle: float = Field(1.0, ge=0)
    azimuth: float = Field(1.0, ge=0)
    camera: float = Field(5.0, ge=0)
    dexterity: float = Field(1.0, ge=0)


class PortPlaceConfig(StrictModel):
    patient: Patient = Patient()
    target: Target = Target()
    robot: Robot = Robot()
    constraints: Constraints = Constraints()
    objective: Objective = Objective()
    search: search_field("grid") = Field("grid", description="'grid' (every assignment, default docking) or a "
                                                             "[search] table: an optimiser over the ports (and the "
                                                             "docking, robot.docking_range_deg)")

    @model_validator(mode="after")
    def _search_objectives_are_columns(self):
        check_objectives(self.search, SEARCH_OBJECTIVES)
        return self

    @model_validator(mode="after")
    def _target_inside_and_ranges_ordered(self):
        for name, (lo, hi) in (("robot.camera_range_mm", self.robot.camera_range_mm),
                               ("constraints.port_to_target_mm", self.constraints.port_to_target_mm),
                               ("constraints.manipulation_angle_deg", self.constraints.manipulation_angle_deg)):
            if not 0 <= lo < hi:
                raise ValueError(f"{name}: [{lo:g}, {hi:g}] must be 0 <= low < high")
        pts = target_points_mm(self.target)
        if len(pts) == 0:
            raise ValueError("target: no sample point (a spacing larger than the target)")
        if len(pts) > 20_000:
            raise ValueError(f"target: {len(pts):,} sample points (at most 20,000: a larger spacing_mm)")
        outside = ~inside_body(pts, self.patient)
        if outside.any():
            p = pts[np.argmax(outside)]
            body = (f"the dome {self.patient.semi_axes_mm} mm over z = 0" if self.patient.shape == "dome"
                    else f"the mesh {self.patient.mesh_file}")
            raise ValueError(f"target: the point ({p[0]:.0f}, {p[1]:.0f}, {p[2]:.0f}) mm is outside the body "
                             f"({body})")
        n = len(sites_mm(self))
        if n < 3:
            raise ValueError(f"patient.port_region: {n} candidate site(s) within constraints.port_to_target_mm; "
                             f"three ports need at least three")
        return self


Config = PortPlaceConfig


# --- the geometry the config implies (numpy; mm) -------------------------------------------------------------

def grid_1d(half: float, spacing: float) -> np.ndarray:
    """Points -half .. half at ``spacing``, symmetric about 0 (0 included when they fit)."""
    k = int(math.floor(half / spacing + 1e-9))
    return np.arange(-k, k + 1) * spacing


def target_points_mm(t: Target) -> np.ndarray:
    """The target sampled on a grid of ``spacing_mm`` centred on it (points inside the shape)."""
    gx, gy, gz = (grid_1d(r, t.spacing_mm) for r in t.radii_mm)
    x, y, z = np.meshgrid(gx, gy, gz, indexing="ij")
    pts = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    if t.shape != "box":
        r = np.asarray(t.radii_mm, float)
        pts = pts[((pts / r) ** 2).sum(axis=1) <= 1.0 + 1e-12]
    return pts + np.asarray(t.centre_mm, float)


def inside_dome(p: np.ndarray, semi_axes_mm) -> np.ndarray:
    a = np.asarray(semi_axes_mm, float)
    return (p[:, 2] >= 0) & (((p / a) ** 2).sum(axis=1) < 1.0)


def dome_height_mm(x, y, semi_axes_mm):
    a, b, c = semi_axes_mm
    s = 1.0 - (np.asarray(x) / a) ** 2 - (np.asarray(y) / b) ** 2
    return c * np.sqrt(np.clip(s, 0.0, None))


#: The largest mesh file read (bytes) and the most triangles accepted.
MAX_MESH_BYTES = 200 * 2 ** 20
MAX_MESH_FACES = 2_000_000


def _read_mesh_bytes(path) -> bytes:
    from surgopt.files import FileProblem, read_bounded

    try:
        return read_bounded(path, MAX_MESH_BYTES)
    except FileNotFoundError:
        raise ValueError(f"mesh_file: file not found: {path}") from None
    except FileProblem as exc:
        raise ValueError(f"mesh_file: {exc}") from None
    except OSError as exc:
        raise ValueError(f"mesh_file: cannot read {path}: {exc.strerror or exc}") from None


@lru_cache(maxsize=4)
def body_mesh(path: str, sha256: str, units: str, offset_mm: tuple):
    """The patient's mesh (trimesh) in mm, offset; a ValueError naming the problem if it cannot be read, is not
    closed (inside and outside would be undefined) or is too large. Cached per file content."""
    import io
    from pathlib import Path

    import trimesh

    data = _read_mesh_bytes(path)
    kind = Path(path).suffix.lower().lstrip(".")
    if kind not in ("stl", "obj", "ply"):
        raise ValueError(f"mesh_file: {path}: not an STL, OBJ or PLY file")
    try:
        mesh = trimesh.load(io.BytesIO(data), file_type=kind, force="mesh", process=True)
    except Exception as exc:  # noqa: BLE001 - whatever trimesh raises on a malformed file
        raise ValueError(f"mesh_file: {path}: cannot be read as {kind.upper()} ({type(exc).__name__}: "
                         f"{str(exc)[:120]})") from None
    if len(mesh.faces) == 0:
        raise ValueError(f"mesh_file: {path}: no triangles")
    if len(mesh.faces) > MAX_MESH_FACES:
        raise ValueError(f"mesh_file: {path}: {len(mesh.faces):,} triangles (at most {MAX_MESH_FACES:,})")
    if not np.all(np.isfinite(mesh.vertices)):
        raise ValueError(f"mesh_file: {path}: a vertex is not finite")
    if not mesh.is_watertight:
        raise ValueError(f"mesh_file: {path}: the mesh is not closed (watertight), so inside and outside the body "
                         f"are undefined; close it (e.g. cap the base plane)")
    mesh.apply_scale(1000.0 if units == "m" else 1.0)
    mesh.apply_translation(np.asarray(offset_mm, float))
    if mesh.bounds[1][2] <= 0:
        raise ValueError(f"mesh_file: {path}: the mesh lies below z = 0 (mesh_offset_mm puts its base on z = 0)")
    return mesh


def _mesh_of(patient: Patient):
    return body_mesh(patient.mesh_file, patient.mesh_sha256, patient.mesh_units, tuple(patient.mesh_offset_mm))


def inside_body(p: np.ndarray, patient: Patient) -> np.ndarray:
    """Which points (mm) lie inside the body: the dome, or the closed mesh (trimesh's containment test)."""
    if patient.shape == "dome":
        return inside_dome(p, patient.semi_axes_mm)
    return np.asarray(_mesh_of(patient).contains(p), bool) & (p[:, 2] >= 0)


def wall_height_mm(x: np.ndarray, y: np.ndarray, patient: Patient) -> np.ndarray:
    """Height (mm) of the body's upper wall over each top-view point: the dome's, or the highest crossing of a
    vertical ray with the mesh (NaN where the ray misses it)."""
    if patient.shape == "dome":
        return dome_height_mm(x, y, patient.semi_axes_mm)
    mesh = _mesh_of(patient)
    top = mesh.bounds[1][2] + 10.0
    origins = np.stack([x, y, np.full(len(x), top)], axis=1)
    dirs = np.tile([0.0, 0.0, -1.0], (len(x), 1))
    locations, index_ray, _ = mesh.ray.intersects_location(origins, dirs, multiple_hits=True)
    z = np.full(len(x), np.nan)
    np.fmax.at(z, index_ray, locations[:, 2])
    return z


def body_extent_mm(patient: Patient) -> tuple[float, float, float]:
    """Half widths in x and y about 0 and the height of the body (the dome's semi-axes, the mesh's bounds)."""
    if patient.shape == "dome":
        return tuple(patient.semi_axes_mm)
    lo, hi = _mesh_of(patient).bounds
    return max(abs(lo[0]), abs(hi[0])), max(abs(lo[1]), abs(hi[1])), float(hi[2])


def sites_mm(cfg: PortPlaceConfig) -> np.ndarray:
    """Candidate ports: a top-view grid at ``site_spacing_mm`` (symmetric about x = 0) lifted onto the body's
    upper wall (the dome, or the mesh by vertical rays), kept where the wall is at least
    ``min_height_fraction`` of the body's height and the target centre is within ``port_to_target_mm``."""
    a, b, c = body_extent_mm(cfg.patient)
    s = cfg.patient.port_region.site_spacing_mm
    gx, gy = np.meshgrid(grid_1d(a, s), grid_1d(b, s), indexing="ij")
    x, y = gx.ravel(), gy.ravel()
    z = wall_height_mm(x, y, cfg.patient)
    keep = np.nan_to_num(z, nan=-1.0) >= cfg.patient.port_region.min_height_fraction * c
    pts = np.stack([x[keep], y[keep], z[keep]], axis=1)
    dist = np.linalg.norm(pts - np.asarray(cfg.target.centre_mm), axis=1)
    lo, hi = cfg.constraints.port_to_target_mm
    return pts[(dist >= lo) & (dist <= hi)]


def arm_limits(arm: dvrk.RcmArm):
    from surgopt.kinematics.port_place import ArmLimits

    return ArmLimits(*arm.yaw_limits_rad, *arm.pitch_limits_rad, *arm.insertion_limits_m, arm.along_shaft_m)


def approach(target: Target):
    """The target's approach cone for the kernel (``port_place.Approach``): a point is reached only where the
    shaft's direction from the port lies within (wrist bend - half-angle) of the approach direction, so that the
    wrist can point the jaws along every direction of the cone; any direction when none is given."""
    from surgopt.kinematics.port_place import Approach

    if target.approach_direction is None:
        return Approach(0.0, 0.0, -1.0, -2.0)  # a cosine below -1: every shaft direction passes
    d = np.asarray(target.approach_direction, float)
    d = d / np.linalg.norm(d)
    return Approach(*d, math.cos(dvrk.LND_WRIST_BEND_RAD - math.radians(target.approach_half_angle_deg)))


def criteria(cfg: PortPlaceConfig):
    from surgopt.kinematics.port_place import Criteria

    k, o = cfg.constraints, cfg.objective
    lo, hi = (math.radians(v) for v in k.manipulation_angle_deg)
    return Criteria(k.dexterity_length_m, lo, hi, math.radians(60.0), k.tip_zone_mm / 1000,
                    (k.shaft_diameter_mm + k.min_shaft_clearance_mm) / 1000, k.min_external_clearance_mm / 1000,
                    dvrk.OUTSIDE_LENGTH_M, k.min_port_spacing_mm / 1000, o.reach, o.angle, o.azimuth, o.camera,
                    o.dexterity)


LATERAL = np.array([1.0, 0.0, 0.0])


@lru_cache(maxsize=4)
def _tables(cfg_json: str):
    """Every per-port and per-pair quantity of a config, computed once per process (the tasks share them)."""
    from surgopt.kinematics import port_place as K

    cfg = PortPlaceConfig.model_validate_json(cfg_json)
    sites = sites_mm(cfg) / 1000
    rot = K.docking_frames(sites, np.asarray(cfg.target.centre_mm, float) / 1000, LATERAL)
    t, reach, dex = port_tables(cfg, sites, rot)
    return sites, t, criteria(cfg), reach, dex


def port_tables(cfg: PortPlaceConfig, sites: np.ndarray, rot: np.ndarray, outside=None):
    """(``PortTables``, reach, isotropy) of ports ``sites`` (m) docked in frames ``rot``; ``outside``: the arms'
    external clearances when the docking is not the default (``external_clearances``)."""
    from surgopt.kinematics import port_place as K

    targets = target_points_mm(cfg.target) / 1000
    centre = np.asarray(cfg.target.centre_mm, float) / 1000
    crit = criteria(cfg)
    reach, dex = K.instrument_tables(sites, rot, targets, arm_limits(dvrk.INSTRUMENT_ARMS[cfg.robot.instrument_arm]),
                                     crit.dexterity_length_m, approach(cfg.target))
    r = cfg.robot
    camera = K.Camera(arm_limits(dvrk.CAMERA_ARMS[r.camera_arm]), math.radians(r.camera_fov_deg) / 2,
                      r.camera_standoff_mm / 1000, r.camera_range_mm[0] / 1000, r.camera_range_mm[1] / 1000)
    coverage = K.camera_coverage(sites, rot, targets, centre, camera)
    pairs = list(K.pair_tables(sites, reach, dex, targets, centre, crit))
    if outside is not None:
        pairs[-1] = outside
    azimuth, side = K.camera_pair_tables(sites, centre, LATERAL)
    spacing = np.linalg.norm(sites[:, None, :] - sites[None, :, :], axis=2)
    tables = K.PortTables(reach.sum(axis=1).astype(np.int64), coverage, *pairs, spacing, azimuth, side,
                          len(targets))
    return tables, reach, dex


@lru_cache(maxsize=4)
def _sites_m(cfg_json: str) -> np.ndarray:
    """The candidate sites (m) of a config, once per process (a search's tasks share them)."""
    return sites_mm(PortPlaceConfig.model_validate_json(cfg_json)) / 1000


def tables(cfg: PortPlaceConfig):
    """(sites m, ``PortTables``, ``Criteria``, reach[site, point], isotropy[site, point]) of a config (memoised
    per process)."""
    return _tables(cfg.model_dump_json())


def n_designs(n_sites: int) -> int:
    """Unordered instrument pairs times the camera ports left: C(n, 2) (n - 2)."""
    return n_sites * (n_sites - 1) // 2 * max(0, n_sites - 2)


def n_total(cfg: PortPlaceConfig) -> int:
    return n_designs(len(sites_mm(cfg)))


#: Designs per task: ~1 s of combining and a few MB of rows.
CHUNK = 200_000


def auto_chunk(cfg) -> int:
    from surgopt.studies import chunk_for_seconds

    return min(CHUNK, chunk_for_seconds(n_total(cfg), NS_PER_DESIGN * 1e-9))


def n_tasks(cfg, chunk: int) -> int:
    return max(1, math.ceil(n_total(cfg) / chunk))


FLOAT_COLUMNS = ("psm1_reach", "psm2_reach", "common_reach", "dexterity_mean", "manipulation_angle_mean_deg",
                 "manipulation_angle_min_deg", "manipulation_angle_max_deg", "manipulation_angle_share_45_75",
                 "manipulation_angle_centre_deg", "azimuth_imbalance_deg", "camera_coverage",
                 "shaft_clearance_mm", "external_clearance_mm", "camera_off_arc_deg")
ANGLE_COLUMNS = {4, 5, 6, 8, 9, 13}


def schema():
    import pyarrow as pa

    fields = [pa.field("design_id", pa.int64()), pa.field("psm1_site", pa.int64()), pa.field("psm2_site", pa.int64()),
              pa.field("ecm_site", pa.int64())]
    fields += [pa.field(f"{arm}_{c}_mm", pa.float64()) for arm in ("psm1", "psm2", "ecm") for c in "xyz"]
    fields += [pa.field(c, pa.float64()) for c in FLOAT_COLUMNS]
    fields += [pa.field("min_port_spacing_mm", pa.float64()), pa.field("psm_to_target_mm", pa.float64()),
               *[pa.field(c, pa.float64()) for c in DOCKING_COLUMNS],
               pa.field("cost", pa.float64()),
               pa.field("score", pa.float64(), metadata={"meaning": "what summarize ranks by (higher is better): "
                                                                     "-cost, less 100 per reason a design fails"}),
               pa.field("feasible", pa.bool_()),
               pa.field("infeasible", pa.int64(), metadata={"meaning": "bit mask: " + "; ".join(
                   f"{bit} {why}" for bit, why in _reasons().items())})]
    return pa.schema(fields)


def _reasons():
    from surgopt.kinematics.port_place import REASONS

    return REASONS


#: What each reason a design fails takes off its score, so that feasible designs rank first.
INFEASIBLE_PENALTY = 100.0


def compute_task(cfg, chunk: int, index: int) -> dict:
    """Designs [index*chunk, (index+1)*chunk) of the enumeration, every port docked toward the target's centre."""
    from surgopt.kinematics.port_place import design_columns

    sites, t, crit, _, _ = tables(cfg)
    start = index * chunk
    stop = min(n_total(cfg), start + chunk)
    ids, f, bad, cost = design_columns(t, crit, start, stop)
    return design_rows(cfg, sites, t, ids, ids, f, bad, cost, np.arange(start, stop, dtype=np.int64),
                       np.zeros((stop - start, 4)))


def design_rows(cfg, sites, t, ids, site_ids, f, bad, cost, design_ids, docking_deg) -> dict:
    """The rows of designs: ``ids`` index ``sites`` and ``t`` (the tables they were combined from), ``site_ids``
    are the candidate sites' numbers reported; ``docking_deg`` (yaw, pitch of PSM1, of PSM2) per design."""
    cols = {"design_id": design_ids, "psm1_site": site_ids[:, 0], "psm2_site": site_ids[:, 1],
            "ecm_site": site_ids[:, 2]}
    for a, arm in enumerate(("psm1", "psm2", "ecm")):
        for c, axis in enumerate("xyz"):
            cols[f"{arm}_{axis}_mm"] = sites[ids[:, a], c] * 1000
    for c, name in enumerate(FLOAT_COLUMNS):
        v = f[:, c]
        cols[name] = np.degrees(v) if c in ANGLE_COLUMNS else (v * 1000 if name.endswith("_mm") else v)
    centre = np.asarray(cfg.target.centre_mm) / 1000
    d = np.linalg.norm(sites - centre, axis=1) * 1000
    cols["min_port_spacing_mm"] = np.minimum(np.minimum(t.spacing[ids[:, 0], ids[:, 1]], t.spacing[ids[:, 0], ids[:, 2]]),
                                             t.spacing[ids[:, 1], ids[:, 2]]) * 1000
    cols["psm_to_target_mm"] = np.maximum(d[ids[:, 0]], d[ids[:, 1]])
    for c, name in enumerate(DOCKING_COLUMNS):
        cols[name] = np.asarray(docking_deg[:, c], dtype=np.float64)
    cols["cost"] = cost
    failed = sum((bad >> bit) & 1 for bit in range(len(_reasons())))
    cols["score"] = -cost - INFEASIBLE_PENALTY * failed
    cols["feasible"] = bad == 0
    cols["infeasible"] = bad
    return cols


#: Free docking (a search's dimensions): each PSM's base turned off the target's centre (0: the default docking).
DOCKING_COLUMNS = ("psm1_docking_yaw_deg", "psm1_docking_pitch_deg", "psm2_docking_yaw_deg", "psm2_docking_pitch_deg")
SITE_COLUMNS = ("psm1_site", "psm2_site", "ecm_site")


def search_plan(cfg):
    """A search's space: the three ports (categorical: any candidate site) and, when
    ``robot.docking_range_deg`` > 0, each PSM's docking yaw and pitch within +- that range."""
    from surgopt.studies.search import SearchPlan, objectives_of, optimiser_of

    spec = optimiser_of(cfg)
    if spec is None:
        return None
    n = len(sites_mm(cfg))
    space = {c: list(range(n)) for c in SITE_COLUMNS}
    r = cfg.robot.docking_range_deg
    if r > 0:
        space.update({c: (-r, r) for c in DOCKING_COLUMNS})
    return SearchPlan(spec, space, objectives_of(spec, OBJECTIVE))


def evaluate_designs(cfg, x: np.ndarray, ids: np.ndarray, source: str) -> dict:
    """Rows of any designs (rows of ``x``: PSM1, PSM2 and ECM site numbers, then the PSMs' docking yaw and
    pitch in deg when free), each from its own three ports docked as given: the per-port and per-pair tables
    of those three (``port_tables``), combined as the enumeration combines them. A design whose ports
    coincide is infeasible (zero spacing and clearance)."""
    from surgopt.kinematics import port_place as K

    x = np.asarray(x, dtype=np.float64).reshape(len(ids), -1)
    all_sites = _sites_m(cfg.model_dump_json())  # not tables(cfg): a worker needs the sites, not every pair
    crit = criteria(cfg)
    centre = np.asarray(cfg.target.centre_mm, float) / 1000
    out = []
    for r in range(x.shape[0]):
        site_ids = x[r, :3].astype(np.int64)
        docking = np.zeros(4) if x.shape[1] == 3 else x[r, 3:7]
        sites = all_sites[site_ids]
        rot = K.tilted_frames(K.docking_frames(sites, centre, LATERAL), np.radians([docking[0], docking[2], 0.0]),
                              np.radians([docking[1], docking[3], 0.0]))
        outside = K.external_clearances(sites, np.ascontiguousarray(rot[:, :, 2]), dvrk.OUTSIDE_LENGTH_M)
        t, _, _ = port_tables(cfg, sites, rot, outside)
        local, f, bad, cost = K.design_columns(t, crit, 0, 1)
        out.append(design_rows(cfg, sites, t, local, site_ids[None, :], f, bad, cost,
                               np.asarray(ids[r:r + 1], dtype=np.int64), docking[None, :]))
    from surgopt.plans import concat_rows

    return concat_rows(out)


def warm_up(cfg) -> None:
    tables(cfg)


#: Cost model: ~60 ns to combine one design and turn it into columns on one core, plus the tables
#: (~3 us per site x target point, ~0.3 us per instrument pair x target point); a row is ~190 bytes.
NS_PER_DESIGN = 60.0
NS_PER_SITE_POINT = 3000.0
NS_PER_PAIR_POINT = 300.0


#: A searched design (its three ports' tables of its own): ~0.43 ms at 915 target points (measured, one core).
NS_PER_SEARCHED_DESIGN_POINT = 470.0


def estimate(cfg) -> Estimate:
    from surgopt.studies.search import optimiser_of

    n = len(sites_mm(cfg))
    m = len(target_points_mm(cfg.target))
    spec = optimiser_of(cfg)
    if spec is not None:
        return Estimate(spec.trials, f"{spec.method} trials", spec.trials,
                        spec.trials * m * NS_PER_SEARCHED_DESIGN_POINT * 1e-9, peak_bytes(spec.trials, 220))
    d = n_designs(n)
    seconds = (d * NS_PER_DESIGN + n * m * NS_PER_SITE_POINT * 1e-3 + n * n / 2 * m * NS_PER_PAIR_POINT) * 1e-9
    return Estimate(d, "port designs", d, seconds, peak_bytes(d, 190, working_bytes=n * n * 8 * 12 + n * m * 9))


def feasible_mask(table):
    return table["feasible"].to_numpy(zero_copy_only=False)


def summary(parts) -> Summary:
    """Feasible count, each reason's count, the best feasible design by cost with its clinical checks."""
    from surgopt.kinematics.port_place import REASONS

    n = parts.num_rows
    by_bit = dict.fromkeys(REASONS, 0)
    feasible = 0
    for t in parts.only(["infeasible"]):  # one pass over one column: every count at once
        bad = t["infeasible"].to_numpy()
        feasible += int(np.count_nonzero(bad == 0))
        for bit in by_bit:
            by_bit[bit] += int(np.count_nonzero(bad & bit))
    counts = {"feasible": feasible, "infeasible": n - feasible}
    counts.update({f"infeasible: {why}": by_bit[bit] for bit, why in REASONS.items()})
    headline = {"designs": n, "feasible": feasible}
    best = _best(parts, 5)
    tables = []
    if best.num_rows:
        b = best.to_pylist()[0]
        headline.update({"best_design_id": b["design_id"], "best_cost": b["cost"]})
        checks = [
            ["port spacing (mm)", f"{b['min_port_spacing_mm']:.0f}", ">= 80 (assumption: 8 cm)"],
            ["instrument port to target centre (mm)", f"{b['psm_to_target_mm']:.0f}", "<= 180 (J Endourol 2004)"],
            ["manipulation angle at the centre (deg)", f"{b['manipulation_angle_centre_deg']:.1f}",
             "45-75, 60 best (Hanna 1997)"],
            ["manipulation angle over the target (deg)", f"{b['manipulation_angle_min_deg']:.1f} - "
             f"{b['manipulation_angle_max_deg']:.1f}", "45-75"],
            ["azimuth imbalance (deg)", f"{b['azimuth_imbalance_deg']:.1f}", "0: equal azimuths (Hanna 1997)"],
            ["optical axis off the instruments' arc (deg)", f"{b['camera_off_arc_deg']:.1f}", "0: camera between them"],
            ["common reach", f"{b['common_reach']:.3f}", "1"],
            ["camera coverage", f"{b['camera_coverage']:.3f}", "1"],
        ]
        tables.append(("best layout: clinical checks", ["quantity", "value", "clinical number"], checks))
        ports = [[arm, str(b[f"{arm}_site"]), f"{b[f'{arm}_x_mm']:.0f}", f"{b[f'{arm}_y_mm']:.0f}",
                  f"{b[f'{arm}_z_mm']:.0f}"] for arm in ("psm1", "psm2", "ecm")]
        tables.append(("best layout: ports (x lateral, y cranial, z anterior)", ["arm", "site", "x_mm", "y_mm", "z_mm"],
                       ports))
        cols = ["design_id", "cost", "common_reach", "dexterity_mean", "manipulation_angle_mean_deg",
                "azimuth_imbalance_deg", "camera_coverage"]
        tables.append(("best feasible designs by cost", cols,
                       [[f"{r[c]:.4g}" if isinstance(r[c], float) else str(r[c]) for c in cols] for r in best.to_pylist()]))
    else:
        headline["best"] = "none: no design is feasible (see the reasons' counts)"
    return Summary(headline, counts, tables)


def _best(parts, k: int):
    """The k feasible designs of least cost (ties by design id), read part by part."""
    import pyarrow as pa

    kept = []
    for t in parts:
        t = t.filter(t["feasible"])
        if t.num_rows:
            order = np.lexsort((t["design_id"].to_numpy(), t["cost"].to_numpy()))[:k]
            kept.append(t.take(pa.array(order)))
    if not kept:
        return parts.schema.empty_table()
    t = pa.concat_tables(kept)
    order = np.lexsort((t["design_id"].to_numpy(), t["cost"].to_numpy()))[:k]
    return t.take(pa.array(order))


STUDY = Study(
    name=NAME, kernel_version=KERNEL_VERSION, config_model=PortPlaceConfig, default_config=DEFAULT_CONFIG,
    help=HELP, config_help=CONFIG_HELP, schema=schema, key_columns=("design_id",), objective=OBJECTIVE,
    auto_chunk=auto_chunk, n_tasks=n_tasks, warm_up=warm_up, compute_task=compute_task, summary=summary,
    feasible_mask=feasible_mask, figures=figures_in("port_place"), estimate=estimate, search_plan=search_plan,
    evaluate=evaluate_designs)
