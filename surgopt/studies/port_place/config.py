"""Config models of the ``port-place`` study: the patient (a dome or a mesh), the port
region and its candidate sites, the target and its points, the robot, the constraints and the objective.

One module of ~590 lines: the sections validate against each other (the cart against the arms and the search,
the target against the patient, the wrist's depth against the insertion), so they are declared together.

A config is resolved once, at validation (a mesh file read, checked and hashed; the sites counted against the
constraints), so the validated config says everything that is hashed into the store key. The geometry itself is
in ``geometry``.
"""
from __future__ import annotations

import math
from typing import Annotated, Literal

import numpy as np
from pydantic import Field, ValidationInfo, field_validator, model_validator

from surgopt.config import NOT_IN_KEY, StrictModel
from surgopt.robots import dvrk
from surgopt.robots.models import CAMERA_ARMS, INSTRUMENT_ARMS, get_model
from surgopt.robots.dvrk.platforms import AUTO_PLATFORM, CART_MODELS, PLATFORMS, cart_models
from surgopt.studies.port_place.geometry import (
    MAX_MESH_BYTES,
    MAX_POINTS_BYTES,
    MAX_TARGET_POINTS,
    body_mesh,
    check_mesh_scale,
    file_points_mm,
    inside_body,
    mesh_points_mm,
    shape_grid_count,
    even_odd_area_mm2,
    site_stages,
    target_points_mm,
)
from surgopt.studies.port_place.arm_config import RcmArmFile, SerialInstrumentArm
from surgopt.studies.port_place.carts import cart_named, cart_of  # noqa: F401 (cart_of: theirs)
from surgopt.plans.search import check_objectives, search_field

#: A 3-vector of a patient-sized quantity: finite and within 10 m (mm) of the patient frame's origin.
Vec3 = list[Annotated[float, Field(ge=-10_000.0, le=10_000.0, allow_inf_nan=False)]]
#: What summarize and a search rank by (higher is better): -cost, less 100 per reason a design fails.
OBJECTIVE = "score"
#: Columns a [search] may optimise.
SEARCH_OBJECTIVES = ("score", "cost", "common_reach", "dexterity_mean", "camera_coverage", "shaft_clearance_mm",
                     "external_clearance_mm", "azimuth_imbalance_deg", "manipulation_angle_share_45_75")


class PortRegion(StrictModel):
    """Where on the wall ports may go: sites on a grid of ``site_spacing_mm`` in the top view, on the dome where
    its height is at least ``min_height_fraction`` of the top (the flanks are too steep to dock), and, when
    ``polygon_mm`` is given, inside that top-view outline (the region a surgeon marks on the abdomen: x lateral,
    y cranial, mm; its vertices in order, not closed), and, for a mesh patient with ``face_color_rgb``, on the faces
    painted that colour (a region painted on the body itself)."""

    site_spacing_mm: float = Field(18.0, ge=5.0, le=200.0)
    min_height_fraction: float = Field(0.45, ge=0.0, lt=1.0)
    polygon_mm: list[Annotated[list[Annotated[float, Field(ge=-2000.0, le=2000.0)]],
                               Field(min_length=2, max_length=2)]] | None = Field(
        None, min_length=3, max_length=1000, description="[[x, y], ...] top-view outline ports must lie inside")
    face_color_rgb: list[Annotated[int, Field(ge=0, le=255)]] | None = Field(
        None, min_length=3, max_length=3, description="a mesh patient: ports only on the faces painted this colour "
                                                      "(a PLY file with per-face colours, as MeshLab or Blender "
                                                      "export a region painted on the body)")

    @model_validator(mode="after")
    def _an_area(self):
        if self.polygon_mm is not None and even_odd_area_mm2(np.asarray(self.polygon_mm, float)) < 1.0:
            raise ValueError("polygon_mm: its vertices enclose no area under the even-odd rule (fewer than three "
                             "distinct, or all on a line)")
        return self


class Organ(StrictModel):
    """An organ the instruments' shafts must not cross on their way to the target (#57 item 1; ``organs.py``): a
    closed triangle mesh in the patient mesh's frame (its ``mesh_units`` and ``mesh_offset_mm``: a CT's organs share
    its frame)."""

    mesh_file: str = Field(min_length=1, description="a closed STL, OBJ or PLY mesh of the organ, relative to the "
                           "config file (its content hash, mesh_sha256, is in the store key, not its path)",
                           json_schema_extra=NOT_IN_KEY)
    mesh_sha256: str | None = Field(None, description="filled in: the mesh file's content hash (in the store key)")
    obstacle: bool = Field(True, description="whether the shafts must not cross it; false for the organ the target "
                                             "is in (a patient file lists every organ, a case sets its target's "
                                             "organ's obstacle = false)")

    @model_validator(mode="after")
    def _read(self, info: ValidationInfo):
        from surgopt.files import resolve_and_hash

        resolve_and_hash(self, "mesh_file", "mesh_sha256", MAX_MESH_BYTES, info.context or {})
        return self


class Patient(StrictModel):
    """The insufflated abdomen: a half-ellipsoid dome over the plane z = 0 (x lateral, patient's left +x; y
    toward the head; z anterior), semi-axes in mm. Default 170 x 210 x 140 mm: an assumption (an adult
    abdomen ~34 cm wide and ~42 cm long; insufflation raises the wall ~6 cm, J Endourol 18(6):572, 2004)."""

    shape: Literal["dome", "mesh"] = Field("dome", description="'dome' (semi_axes_mm) or 'mesh' (mesh_file)")
    semi_axes_mm: Vec3 = Field([170.0, 210.0, 140.0], min_length=3, max_length=3)
    dome_exponent: float = Field(2.0, ge=2.0, le=10.0, description="the dome |x/a|^n + |y/b|^n + |z/c|^n <= 1: 2, a "
                                 "half-ellipsoid; above 2, a superquadric, its top flatter and its flanks steeper "
                                 "(an assumption either way: no source gives an insufflated shape)")
    mesh_file: str | None = Field(None, min_length=1, description="a closed triangle mesh of the insufflated body "
                                  "(STL, OBJ or PLY, read by trimesh), relative to the config file (its content "
                                  "hash, mesh_sha256, is in the store key, not its path)",
                                  json_schema_extra=NOT_IN_KEY)
    mesh_units: Literal["mm", "m"] = Field("mm", description="the mesh file's length unit")
    mesh_is: Literal["body", "wall"] = Field(
        "body", description="'body': the mesh closes the insufflated body (inside it is the body); 'wall': it is the "
        "abdominal wall's shell as a CT gives it (outer skin and inner peritoneum, e.g. OpenHELP's), and the body is "
        "everything under its outer skin above the table (the cavity too): a point is inside where a vertical ray "
        "up from it meets the wall")
    mesh_offset_mm: Vec3 = Field([0.0, 0.0, 0.0], min_length=3, max_length=3,
                                 description="added to the mesh (after units): its base on z = 0, x lateral, y "
                                             "toward the head, z anterior, as for the dome")
    mesh_sha256: str | None = Field(None, description="filled in: the mesh file's content hash (in the store key)")
    port_region: PortRegion = PortRegion()
    organs: dict[Annotated[str, Field(min_length=1, max_length=40, pattern=r"^[A-Za-z][\w -]*$")], Organ] = Field(
        {}, max_length=30, description="organs as obstacles ({name = {mesh_file = ...}}): no instrument's shaft may "
        "cross one on its way to a target point (each taken as its 2 mm voxels, so a little larger than itself); "
        "in the patient mesh's frame, units and offset; the organ the target is in: obstacle = false")
    landmarks_mm: dict[Annotated[str, Field(min_length=1, max_length=40, pattern=r"^[A-Za-z][\w -]*$")],
                       Annotated[list[Annotated[float, Field(ge=-2000.0, le=2000.0, allow_inf_nan=False)]],
                                 Field(min_length=2, max_length=2)]] | None = Field(
        None, max_length=50, description="named landmarks on the patient, top view ({name = [x, y]} mm, the patient "
        "frame: the umbilicus, the pubis, the xiphoid, a costal margin's point...), that the report measures each "
        "port from; none: for the dome, xiphoid, umbilicus and pubis on the midline at +0.85, 0 and -0.85 of its "
        "cranio-caudal semi-axis (assumptions), for a mesh the frame's origin")
    reference_landmark: str | None = Field(None, description="the landmark ports are measured from (one of "
                                                             "landmarks_mm; none: the umbilicus, or the first)")
    landmark_lines: list[Annotated[list[Annotated[str, Field(min_length=1, max_length=40)]],
                                   Field(min_length=2, max_length=2)]] | None = Field(
        None, max_length=20, description="lines between landmarks drawn on the skin and measured along it "
        "([[a, b], ...], names of landmarks_mm: e.g. the umbilicus to an anterior superior iliac spine, Monro's "
        "line); none: the midline's chain (the landmarks on x = 0, head to feet)")

    @model_validator(mode="after")
    def _a_known_reference(self):
        if self.reference_landmark is None and not self.landmark_lines:
            return self
        from surgopt.studies.port_place.geometry import landmarks_mm

        names = list(landmarks_mm(self))
        for line in self.landmark_lines or []:
            for name in line:
                if name not in names:
                    raise ValueError(f"landmark_lines: {name!r} is not a landmark of this patient ({', '.join(names)})")
        if self.reference_landmark is None:
            return self
        if self.reference_landmark not in names:
            raise ValueError(f"reference_landmark: {self.reference_landmark!r} is not a landmark of this patient "
                             f"({', '.join(names)}; name it in landmarks_mm)")
        return self

    @model_validator(mode="after")
    def _positive(self, info: ValidationInfo):
        if not all(20.0 <= v <= 1000.0 for v in self.semi_axes_mm):
            raise ValueError(f"semi_axes_mm: {self.semi_axes_mm}: every semi-axis of an abdomen is 20 to 1,000 mm")
        if self.shape == "mesh":
            if self.dome_exponent != 2.0:
                raise ValueError("dome_exponent shapes the parametric dome; it goes with shape = 'dome', not a mesh")
            self._resolve_mesh(info.context or {})
        elif self.mesh_file is not None:
            raise ValueError("mesh_file is given but shape is 'dome': set shape = 'mesh' to use it")
        return self

    def _resolve_mesh(self, context) -> None:
        """The mesh file, relative to the config's folder, read (bounded), hashed and checked closed."""
        from surgopt.files import resolve_and_hash

        if self.mesh_file is None:
            raise ValueError("shape = 'mesh' needs mesh_file (an STL, OBJ or PLY file)")
        path, sha = resolve_and_hash(self, "mesh_file", "mesh_sha256", MAX_MESH_BYTES, context)
        if sha is None:
            return
        mesh = body_mesh(str(path), sha, self.mesh_units, tuple(self.mesh_offset_mm))  # parsed and checked once here
        check_mesh_scale(mesh, str(path), self.mesh_units, 20.0, 1000.0, "an abdomen's")


class Target(StrictModel):
    """The anatomy every instrument must reach: a sphere, ellipsoid or box (``radii_mm``: semi-axes, or half
    sides), sampled on a grid of ``spacing_mm``, the points of a file (``shape = "points"``), or a closed mesh
    of the organ or region (``shape = "mesh"``: the grid points inside it). Default: an ellipsoid of 35 x 45 x 30
    mm semi-axes in the pelvis, 100 mm caudal of the dome's top and 40 mm above its base (a prostate-bed-like
    target; an assumption)."""

    shape: Literal["sphere", "ellipsoid", "box", "points", "mesh"] = "ellipsoid"
    mesh_file: str | None = Field(None, min_length=1, description="shape = 'mesh': a closed triangle mesh of the "
                                  "region to reach (STL, OBJ or PLY), relative to the config file; sampled on the "
                                  "grid of spacing_mm; its sha256 is in the store key", json_schema_extra=NOT_IN_KEY)
    mesh_sha256: str | None = Field(None, description="filled in: the target mesh's content hash")
    mesh_units: Literal["mm", "m"] = "mm"
    mesh_offset_mm: Vec3 = Field([0.0, 0.0, 0.0], min_length=3, max_length=3,
                                 description="added to the target mesh (after units), into the patient frame")
    region_box_mm: list[Vec3] | None = Field(
        None, min_length=2, max_length=2, description="shape = 'mesh': only the organ's points within this box "
        "([[x, y, z] low, [x, y, z] high], patient frame): a region of the organ (a pancreas's tail, a liver's "
        "segment)")
    points_file: str | None = Field(None, min_length=1, description="shape = 'points': a text file of x y z rows "
                                    "(commas or spaces; '#' comments) or a .npy array, in the patient frame, "
                                    "relative to the config file; its sha256 is in the store key",
                                    json_schema_extra=NOT_IN_KEY)
    points_sha256: str | None = Field(None, description="filled in: the points file's content hash")
    points_units: Literal["mm", "m"] = "mm"
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
    def _points_from_the_file(self, info: ValidationInfo):
        """shape = 'points': the file resolved, read (bounded), hashed and checked; centre_mm, when not given,
        the points' centroid and radii_mm their half extents (what the figures outline)."""
        if self.shape != "mesh" and self.mesh_file is not None:
            raise ValueError("mesh_file is given but shape is not 'mesh': set shape = 'mesh' to use it")
        if self.region_box_mm is not None and (self.shape != "mesh" or not all(
                lo < hi for lo, hi in zip(*self.region_box_mm))):
            raise ValueError("region_box_mm: a box ([[x, y, z] low, [x, y, z] high], each low below its high) "
                             "of a target mesh (shape = 'mesh')")
        if self.shape == "mesh":
            return self._resolve_mesh(info.context or {})
        if self.shape != "points":
            if self.points_file is not None:
                raise ValueError("points_file is given but shape is not 'points': set shape = 'points' to use it")
            return self
        if self.points_file is None:
            raise ValueError("shape = 'points' needs points_file (x y z rows, or a .npy array)")
        path, sha = self._resolved("points_file", "points_sha256", MAX_POINTS_BYTES, info.context or {})
        if sha is None:
            return self
        return self._centre_and_extent(file_points_mm(str(path), sha, self.points_units))

    def _resolved(self, field: str, sha_field: str, max_bytes: int, context: dict):
        """The file of ``field`` resolved against the config's folder (set back as a path), and, unless the config
        is read as stored, read (bounded) and hashed into ``sha_field``: (path, sha256 or None when stored)."""
        from surgopt.files import resolve_and_hash

        return resolve_and_hash(self, field, sha_field, max_bytes, context)

    def _resolve_mesh(self, context):
        """shape = 'mesh': the file resolved, read (bounded, closed), hashed, sampled; centre and extent from its
        points as for a points file."""
        if self.mesh_file is None:
            raise ValueError("shape = 'mesh' needs mesh_file (a closed STL, OBJ or PLY mesh of the region)")
        if self.points_file is not None:
            raise ValueError("points_file goes with shape = 'points', not 'mesh'")
        path, sha = self._resolved("mesh_file", "mesh_sha256", MAX_MESH_BYTES, context)
        if sha is None:
            return self
        check_mesh_scale(body_mesh(str(path), sha, self.mesh_units, tuple(self.mesh_offset_mm)), str(path),
                         self.mesh_units, 1.0, 300.0, "a target region's")
        pts = target_points_mm(self)  # the organ's points, within region_box_mm when given
        if not len(pts):
            raise ValueError(f"region_box_mm: no point of {path} (on the {self.spacing_mm:g} mm grid) lies in the box")
        return self._centre_and_extent(pts)

    def _centre_and_extent(self, pts: np.ndarray):
        """centre_mm, when not given, the points' centroid, and radii_mm their half extents (what the figures
        outline)."""
        if "centre_mm" not in self.model_fields_set:
            object.__setattr__(self, "centre_mm", [round(float(v), 6) for v in pts.mean(axis=0)])
        if "radii_mm" not in self.model_fields_set:
            half = np.maximum(np.abs(pts - np.asarray(self.centre_mm)).max(axis=0), 1.0)
            object.__setattr__(self, "radii_mm", [round(float(v), 6) for v in half])
        return self

    @model_validator(mode="after")
    def _positive(self):
        if min(self.radii_mm) <= 0:
            raise ValueError("radii_mm: every radius must be > 0")
        if self.approach_direction is not None:
            if math.hypot(*self.approach_direction) < 1e-9:
                raise ValueError("approach_direction: must be a direction, not [0, 0, 0]")
        elif self.approach_half_angle_deg:
            raise ValueError("approach_half_angle_deg goes with approach_direction")
        return self


class Robot(StrictModel):
    instrument_arm: Literal[INSTRUMENT_ARMS] = "dvrk_psm_classic"
    instrument_file: RcmArmFile | None = Field(None, description="any RCM instrument arm from a URDF or DH table, "
                                               "in place of instrument_arm")
    instrument_serial: SerialInstrumentArm | None = Field(
        None, description="a serial arm (a shipped model, URDF or DH table, as rcm-grid takes arms) holding the "
                          "instrument and keeping the RCM at the port in software, in place of instrument_arm")
    camera_file: RcmArmFile | None = Field(None, description="any RCM endoscope arm from a URDF or DH table, in "
                                           "place of camera_arm")
    camera_serial: SerialInstrumentArm | None = Field(
        None, description="a serial arm holding the endoscope and keeping its RCM at the port in software (as "
                          "instrument_serial), in place of camera_arm")
    instrument_count: Literal[2, 3] = Field(2, description="instrument arms: 2 (PSM1, PSM2: the surgeon's hands) or "
                                                            "3 (and PSM3, the third arm: it must reach the target and "
                                                            "clear the others; the angles are the working pair's)")
    camera_arm: Literal[CAMERA_ARMS] = "dvrk_ecm_classic"
    camera_fov_deg: float = Field(70.0, gt=0, lt=180, description="full view angle of a 0-deg scope (60-70 typical)")
    camera_standoff_mm: float = Field(100.0, gt=0, description="the scope's tip stops this far before the target "
                                      "centre, where the port's distance allows: never shallower than "
                                      "camera_min_insertion_mm (then nearer the centre)")
    camera_min_insertion_mm: float | None = Field(
        None, ge=0.0, le=300.0, description="the endoscope's least insertion (its arm's q3) at every port: the "
        "scope out of its cannula and inside the body; none: the arm's own controller limit (the dVRK ECM refuses "
        "Cartesian control until q3 > 50 mm, is_safe_for_cartesian_control; 0 for an arm from a file)")
    camera_range_mm: list[float] = Field([10.0, 200.0], min_length=2, max_length=2,
                                         description="sharp imaging range from the tip")
    camera_scope_angle_deg: float = Field(0.0, ge=0.0, le=60.0,
                                          description="the endoscope's view axis off its shaft (0: straight; "
                                                      "30: the common angled scope, dvrk-kinematics.md)")
    camera_scope_view: Literal["down", "up"] = Field("down", description="an angled scope looks toward the "
                                                     "patient's back (down: its shaft passes above the target) "
                                                     "or front (up)")
    docking_range_deg: float = Field(0.0, ge=0.0, le=60.0,
                                     description="a [search] may turn each PSM's base this far (yaw and pitch) off "
                                                 "the target's centre (free docking), a serial arm's base this far "
                                                 "about its port (yaw); 0: docked toward the centre. The grid "
                                                 "enumerates the default docking only")

    tip_beyond_wrist_mm: float | None = Field(
        None, ge=0.0, le=100.0, description="the point that must reach every target point lies this far past the "
        "instrument's wrist-pitch point along its shaft (the wrist straight); none: the instrument's own jaw tip "
        "(the dVRK Large Needle Driver's 9.1 mm, its wrist-yaw link; 0 for an arm from a file); 0: the "
        "wrist-pitch point (as before issue 40)")
    min_wrist_depth_mm: float | None = Field(
        None, ge=0.0, le=300.0, description="the instrument's wrist at least this far inside the body, from the "
        "RCM (the port), at every target point; none: the arm's own controller limit (the dVRK PSM refuses "
        "Cartesian control within 45 mm, SafeDistanceFromRCM; 0 for an arm from a file)")
    docking_roll_deg: float = Field(
        0.0, ge=-90.0, le=90.0, description="each instrument arm's base turned about its neutral shaft by this "
        "angle after docking: 0, its yaw swings the shaft across the patient; 90, head to foot. Ports on the "
        "patient's left (x >= 0) turn the frame's x toward the head, on the right toward the feet (mirror "
        "images, so a symmetric patient gives a symmetric answer); a negative angle turns each the other way. On "
        "the Si (whose setup joints fix the roll) the base's yaw off psi*, mirrored the same way")
    docking_roll_right_deg: float | None = Field(
        None, ge=-90.0, le=90.0, description="the ports on the patient's right (x < 0) rolled by this instead of "
        "docking_roll_deg (read as its mirror image, as docking_roll_deg is there): the two sides' PSMs docked at "
        "rolls of their own; unset: docking_roll_deg on both sides")
    docking_rolls_per_side: bool = Field(
        False, description="with docking_rolls_deg: a block of the enumeration per pair of rolls, one for the ports "
                           "on the patient's left and one for those on the right (the list's length squared), so "
                           "that two PSMs on either side of the midline take rolls of their own")
    docking_rolls_deg: list[Annotated[float, Field(ge=-90.0, le=90.0, allow_inf_nan=False)]] | None = Field(
        None, min_length=1, max_length=12,
        description="the docking roll as a dimension of the enumeration (#54): every layout docked at each of these "
                    "rolls (each as docking_roll_deg, mirrored by the port's side), one block of designs per roll in "
                    "this order (design_id's block says its roll; the rows' psm1_roll_deg ... the signed roll), the "
                    "answer the cheapest feasible row over all; unset: docking_roll_deg alone. With docking_roll = "
                    "'given'; on the Si each is a yaw of the setup joints off psi*, not a roll; the time and the "
                    "tables' memory grow with the count")
    docking_roll: Literal["given", "most_reach", "search"] = Field(
        "given", description="'given': docking_roll_deg at every port; 'most_reach': at each port the roll of "
                             "0, 15, ..., 90 deg (mirrored as docking_roll_deg) that reaches the most target "
                             "points (ties: the one nearest docking_roll_deg); 'search': each PSM's roll a "
                             "dimension of a [search] (psm1_roll_deg ..., -90 to 90 deg, x toward y at its own port, "
                             "not mirrored), its setup joints and links docked so in each trial")

    @model_validator(mode="after")
    def _rcm_instrument_choices(self):
        if self.instrument_serial is None:
            return self
        for name in ("tip_beyond_wrist_mm", "min_wrist_depth_mm", "docking_roll_deg", "docking_roll",
                     "docking_rolls_deg", "docking_roll_right_deg", "docking_rolls_per_side"):
            if getattr(self, name) != type(self).model_fields[name].default:  # a stored config lists every field
                raise ValueError(f"{name} goes with an RCM instrument arm (instrument_arm or instrument_file); a "
                                 f"serial arm's tool is its own tool_m, its base turns by docking_range_deg")
        return self

    @model_validator(mode="after")
    def _rolls_enumerated_once_each(self):
        rolls = self.docking_rolls_deg
        if rolls is None:
            return self
        if self.docking_roll != "given":
            raise ValueError(f"docking_rolls_deg enumerates the rolls itself: docking_roll must be 'given' (not "
                             f"{self.docking_roll!r})")
        if len(set(rolls)) != len(rolls):
            raise ValueError(f"docking_rolls_deg lists a roll twice ({rolls}): each is a block of the enumeration")
        if self.docking_roll_deg != 0.0 or self.docking_roll_right_deg is not None:
            raise ValueError("give docking_rolls_deg (every roll enumerated) or docking_roll_deg and "
                             "docking_roll_right_deg (one docking), not both")
        return self

    @model_validator(mode="after")
    def _a_sides_roll_is_given(self):
        if self.docking_roll_right_deg is not None and self.docking_roll != "given":
            raise ValueError(f"docking_roll_right_deg goes with docking_roll = 'given' (not {self.docking_roll!r})")
        if self.docking_rolls_per_side and not self.docking_rolls_deg:
            raise ValueError("docking_rolls_per_side pairs the rolls of docking_rolls_deg: give the list")
        return self

    @model_validator(mode="after")
    def _one_arm_each(self):
        for role in ("instrument", "camera"):
            if getattr(self, f"{role}_serial") is None:
                continue
            if getattr(self, f"{role}_file") is not None:
                raise ValueError(f"give {role}_serial (a serial arm) or {role}_file (an RCM mechanism), not both")
            if getattr(self, f"{role}_arm") != type(self).model_fields[f"{role}_arm"].default:
                raise ValueError(f"give {role}_serial (a serial arm) or {role}_arm (a shipped dVRK arm), not both")
        return self


class Constraints(StrictModel):
    min_port_spacing_mm: float = Field(80.0, ge=0, description="between any two ports (assumption: 8 cm)")
    port_to_target_mm: list[float] = Field([80.0, 180.0], min_length=2, max_length=2,
                                           description="candidate sites this far from the target centre, "
                                                       "measured as port_to_target_measure says (<= 18 cm: J "
                                                       "Endourol 18(6):572, 2004, from the pubis on the "
                                                       "insufflated skin)")
    port_to_target_measure: Literal["3d", "horizontal"] = Field(
        "3d", description="'3d': the straight distance from port to target centre; 'horizontal': its top-view "
                          "part (x, y) alone, as the J Endourol figure is read (a port 18 cm from the pubis "
                          "along the table)")
    shaft_diameter_mm: float = Field(dvrk.INSTRUMENT_SHAFT_DIAMETER_MM, gt=0)
    min_shaft_clearance_mm: float = Field(5.0, ge=0, description="between shaft surfaces inside the body")
    tip_zone_mm: float = Field(30.0, ge=0, description="last stretch before the target centre left out of the "
                                                        "shafts' clearance (the instruments meet there)")
    min_external_clearance_mm: float = Field(60.0, ge=0, description="between arm axes outside the body, along "
                                                                     "the 0.4318 m behind each port (without "
                                                                     "the cart: with it the links decide)")
    min_link_clearance_mm: Annotated[float, Field(ge=-25.0, le=500.0)] | Literal["off"] = Field(
        0.0, description="with the cart: the least clearance (mm) between the arms' links outside the body (setup "
                         "joints and the arms' own, capsules), docked and over the target, that a feasible layout "
                         "keeps at its cart pose, and of each arm to the patient's body and the table (replaces "
                         "the shaft lines' min_external_clearance_mm); 'off': feasible leaves the links out and "
                         "the closing report checks the best layouts' only; at least -25 (an overlap under the "
                         "thinnest link's 30 mm radius: a link inside the body reads as its radius)")

    @property
    def link_least_mm(self) -> float | None:
        """``min_link_clearance_mm`` as a number, None when 'off'."""
        v = self.min_link_clearance_mm
        return None if v == "off" else float(v)

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


class Cart(StrictModel):
    """The dVRK patient cart (issue 40): its setup joints (``robots/dvrk/suj.py``) must put each arm's base at its
    port, docked as the rows assume (the neutral shaft through the target's centre). "none": docking is assumed,
    as before the cart was modelled. "classic": the Classic cart; every arm's setup joints are solved for each port
    and cart pose (``kinematics.port.suj``: the PSMs' docked toward the target's centre, the ECM's with its own yaw and
    pitch aiming the scope), and a layout is dockable when at one cart pose every arm's SUJ has a solution within
    its ranges (PSM1 and PSM2 on either of the pair's ports). The arms' links are not checked against each other
    yet: a dockable layout is one the setup joints can reach.

    The cart stands on the floor (its world frame's origin and heading, in the patient's floor frame: x lateral,
    y cranial, mm; heading 0 = its arms reach toward +y, the patient's head) at a ``given`` pose or at each pose
    of a ``grid`` around the target: around_deg from the patient's feet (0 at the foot end, +90 the patient's
    left), distance_mm from the target's centre (horizontal), facing the target turned by each of
    yaw_offsets_deg; poses whose base falls within ``clear_of_table_mm`` of the table are left out; or, with a
    [search], at a pose ``search``ed on that arc (each trial its own; one too near the table docks nothing). The
    patient's frame is on the table top (``table_height_mm`` above the floor), tilted head down by
    ``trendelenburg_deg`` and left side up by ``lateral_tilt_deg``."""

    model: str = Field(
        "auto", description="'none': docking assumed; 'classic': the Classic cart's setup joints solved; 'si': the "
                            "Si cart's (its PSMs and ECM, robot.instrument_arm = 'dvrk_psm_si', camera_arm = "
                            "'dvrk_ecm_si'; each arm docked at the one orientation its setup joints give nearest "
                            "the aim, its own yaw and pitch absorbing the rest; its links from the dVRK's Si "
                            "description); 'auto' "
                            "(the default): 'classic' where its arms are the Classic PSMs and ECM on "
                            "the grid of layouts, 'none' otherwise (a note says why); resolved when the config is "
                            "read, so the stored config names the one used",
        json_schema_extra={"enum": list(CART_MODELS)})
    pose: Literal["grid", "given", "search"] = Field(
        "grid", description="'grid': every pose of the grid below, a layout's the one at which its links clear most "
                            "(without the links in feasible: its first that docks); 'given': x_mm, "
                            "y_mm, heading_deg; 'search': a [search]'s dimensions (cart_around_deg, "
                            "cart_distance_mm, cart_yaw_offset_deg within around_deg, distance_mm and the range of "
                            "yaw_offsets_deg), each trial docked at its own pose")
    x_mm: float = Field(0.0, ge=-5000.0, le=5000.0, description="given pose: the cart's origin, lateral")
    y_mm: float = Field(-1100.0, ge=-5000.0, le=5000.0, description="given pose: the cart's origin, cranial")
    heading_deg: float = Field(0.0, ge=-180.0, le=180.0, description="given pose: where its arms reach, from +y "
                                                                     "toward +x")
    around_deg: list[float] = Field([-90.0, 90.0], min_length=2, max_length=2,
                                    description="grid: the arc of positions around the target (0: at the feet)")
    around_step_deg: float = Field(15.0, gt=0.0, le=180.0)
    distance_mm: list[float] = Field([900.0, 1500.0], min_length=2, max_length=2,
                                     description="grid: the cart origin's horizontal distance from the target")
    distance_step_mm: float = Field(150.0, gt=0.0, le=2000.0)
    yaw_offsets_deg: list[Annotated[float, Field(ge=-90.0, le=90.0)]] = Field(
        [-20.0, 0.0, 20.0], min_length=1, max_length=32, description="grid: headings off facing the target")
    table_height_mm: float = Field(800.0, ge=400.0, le=1300.0, description="the table top (the patient frame's "
                                                                             "z = 0) above the floor (assumption)")
    table_half_width_mm: float = Field(280.0, ge=100.0, le=1000.0, description="the table, about the patient's "
                                                                               "midline (assumption)")
    table_y_mm: list[float] = Field([-1000.0, 1000.0], min_length=2, max_length=2,
                                    description="the table's foot and head ends, cranial (assumption)")
    clear_of_table_mm: float = Field(50.0, ge=0.0, le=2000.0, description="the cart's base (its platform's "
                                     "footprint, from the cart's own mesh) at least this far from the table top's "
                                     "outline on the floor (assumed: a hand's width; the base is not let under the "
                                     "table, whose pedestal is not modelled)")
    mount_below_table_top: Literal["refuse", "allow"] = Field(
        "refuse", description="'refuse': a PSM does not dock where its setup joints would hold its mount (their last "
                              "frame, where the arm's own links begin) below the table top: beside the table stand "
                              "the patient's arms, the arm boards and the rails (issue 54; the bedside's boxes hold them at "
                              "assumed sizes, [bedside]); 'allow': it may")
    trendelenburg_deg: float = Field(0.0, ge=-40.0, le=40.0, description="head down (positive) or up")
    lateral_tilt_deg: float = Field(0.0, ge=-40.0, le=40.0, description="the patient's left side up (positive)")

    @field_validator("model")
    @classmethod
    def _a_platform(cls, model: str) -> str:
        """One of ``CART_MODELS``, read from the platform registry when the config is validated (not when this
        module was imported), so that a platform registered later is a value like the others."""
        names = cart_models()
        if model not in names:
            raise ValueError(f"Input should be {', '.join(repr(n) for n in names[:-1])} or {names[-1]!r}")
        return model

    @model_validator(mode="after")
    def _ordered(self):
        for name in ("around_deg", "distance_mm", "table_y_mm"):
            lo, hi = getattr(self, name)
            if not lo <= hi:
                raise ValueError(f"{name}: [{lo:g}, {hi:g}] must be low <= high")
        if self.distance_mm[0] <= 0:
            raise ValueError("distance_mm: must be > 0")
        return self

    @model_validator(mode="after")
    def _a_grid_the_run_can_hold(self):
        """The grid's poses counted by arithmetic (never built to be counted, issue 55 item 6), refused past
        ``MAX_CART_POSES`` naming the step that makes it so."""
        if self.pose != "grid":
            return self
        counts = {"around_step_deg": grid_count(self.around_deg, self.around_step_deg),
                  "distance_step_mm": grid_count(self.distance_mm, self.distance_step_mm)}
        total = counts["around_step_deg"] * counts["distance_step_mm"] * len(self.yaw_offsets_deg)
        if total > MAX_CART_POSES:
            worst = max(counts, key=counts.get)
            raise ValueError(f"{worst}: {getattr(self, worst):g} makes {total:,.0f} cart poses (around "
                             f"{counts['around_step_deg']:,.0f} x distance {counts['distance_step_mm']:,.0f} x "
                             f"{len(self.yaw_offsets_deg)} headings), more than the {MAX_CART_POSES:,} a run "
                             f"docks at (each arm's setup joints are solved at every site and pose); take a "
                             f"larger step")
        return self


#: The most cart poses a grid may have: the dock tables hold each arm's joints at every site and pose (at 164 sites,
#: 10,000 poses are ~240 MB a PSM); the default has 150.
MAX_CART_POSES = 10_000


def grid_count(span, step: float) -> float:
    """How many values ``numpy.arange(lo, hi + 1e-9, step)`` takes (``tables.grid_places``), by arithmetic: a float,
    so that a step of 1e-300 counts (as inf) instead of building the array."""
    lo, hi = span
    return math.floor((hi + 1e-9 - lo) / step) + 1 if (hi - lo) / step < 1e15 else math.inf


class Bedside(StrictModel):
    """What stands on and beside the table, as boxes the arms' links must clear (``bedside.py``, #54): the side
    rails, the patient's arms and legs. With the cart's links only."""

    rails: bool = Field(True, description="the table's side rails along both long sides (ISO 19054's 25 x 10 mm "
                                          "profile; its stand-off 20 mm, an assumption)")
    arms: Literal["tucked", "out", "none"] = Field(
        "out", description="the patient's arms: 'out' on arm boards at 90 deg at the shoulders (a board 150 x 660 mm, "
                           "the arm 120 mm above it), 'tucked' at the sides on the table's edge (110 mm wide, 120 mm "
                           "high, 750 mm from the shoulder), or 'none' (sizes: assumptions)")
    legs: Literal["flat", "lithotomy", "none"] = Field(
        "none", description="the patient's legs: 'none' (not modelled: the default cart docks from the side), 'flat' "
                            "on the table from the hips to its foot end (each 180 mm wide, 170 mm high), or "
                            "'lithotomy' up in stirrups (each a box 450 mm from the hip, 100-500 mm off the midline, "
                            "800 mm high: docking from the foot between them) (sizes: assumptions)")
    shoulder_y_mm: float = Field(420.0, ge=-3000.0, le=3000.0, allow_inf_nan=False,
                                 description="the shoulders' level, cranial in the patient frame (assumption: 420 mm "
                                             "above the umbilicus, the dome's origin)")
    hip_y_mm: float = Field(-220.0, ge=-3000.0, le=3000.0, allow_inf_nan=False,
                            description="the hips' level, cranial in the patient frame (assumption: 220 mm below the "
                                        "umbilicus)")

    @model_validator(mode="after")
    def _shoulders_above_hips(self):
        if self.shoulder_y_mm <= self.hip_y_mm:
            raise ValueError(f"bedside.shoulder_y_mm ({self.shoulder_y_mm:g}) must lie cranial of bedside.hip_y_mm "
                             f"({self.hip_y_mm:g})")
        return self


class GivenPort(StrictModel):
    """One arm's port of a surgeon's own layout (``[given_layout]``): a top-view point of the patient frame (x_mm,
    y_mm), or a landmark and offsets from it along the patient's left and toward the head (mm); taken to the nearest
    candidate site (the report says how far that is)."""

    x_mm: float | None = Field(None, ge=-2000.0, le=2000.0, description="top view, the patient's left positive")
    y_mm: float | None = Field(None, ge=-2000.0, le=2000.0, description="top view, toward the head positive")
    landmark: str | None = Field(None, description="a landmark of the patient (patient.landmarks_mm, or the dome's)")
    left_mm: float = Field(0.0, ge=-1000.0, le=1000.0, description="from the landmark toward the patient's left "
                                                                   "(negative: right)")
    cranial_mm: float = Field(0.0, ge=-1000.0, le=1000.0, description="from the landmark toward the head "
                                                                      "(negative: caudal)")

    @model_validator(mode="after")
    def _a_point_or_a_landmark(self):
        point = self.x_mm is not None and self.y_mm is not None
        if point == (self.landmark is not None) or (self.x_mm is None) != (self.y_mm is None):
            raise ValueError("a given port is x_mm and y_mm (the patient frame, top view), or a landmark with left_mm "
                             "and cranial_mm: one of the two")
        if point and (self.left_mm or self.cranial_mm):
            raise ValueError("left_mm and cranial_mm go with a landmark, not with x_mm and y_mm")
        return self


class GivenLayout(StrictModel):
    """A surgeon's own layout (#57 item 3): each arm's port; the closing report scores it as the rows score a layout
    (every check, the docking, the links, the hands), says what it fails on, its rank among the run's feasible
    layouts and the cheapest feasible layout with every port within ``within_mm`` of it."""

    psm1: GivenPort
    psm2: GivenPort
    psm3: GivenPort | None = None
    ecm: GivenPort
    within_mm: float = Field(50.0, gt=0.0, le=300.0, description="how far (3-D, each port) a better layout may move "
                                                                   "the given ports")


class PortPlaceConfig(StrictModel):
    patient: Patient = Patient()
    target: Target = Target()
    robot: Robot = Robot()
    constraints: Constraints = Constraints()
    objective: Objective = Objective()
    cart: Cart = Cart()
    bedside: Bedside = Bedside()
    rows_stored: Literal["all", "feasible"] = Field("all", description="'feasible': store only the feasible "
                                                    "designs' rows (the 3-PSM enumeration's 3.5 x 10^8 designs "
                                                    "would fill ~15 GB on disk at the 44 bytes a row measured for "
                                                    "the default run); the summary counts the rest without their "
                                                    "reasons")
    search: search_field("grid") = Field("grid", description="'grid' (every assignment, default docking) or a "
                                                             "[search] table: an optimiser over the ports (and the "
                                                             "docking, robot.docking_range_deg)")
    search_ports: Literal["sites", "surface"] = Field(
        "sites", description="how a [search] places a port: 'sites', a categorical choice of candidate site, or "
                             "'surface', a top-view point (x, y mm) taken to the nearest candidate site, so that "
                             "the optimiser sees neighbouring ports as neighbours")
    given_layout: GivenLayout | None = Field(
        None, description="a surgeon's own layout the closing report scores beside the answer (#57 item 3); not in the "
        "run's key: another layout is scored against the same stored rows, in seconds", json_schema_extra=NOT_IN_KEY)

    @model_validator(mode="after")
    def _the_cart_carries_its_arms(self):
        if self.cart.model == "auto":
            object.__setattr__(self.cart, "model", "none" if cart_does_not_carry(self, AUTO_PLATFORM) else AUTO_PLATFORM)
        if not cart_named(self.cart.model).docks:
            return self
        if self.cart.pose == "search" and self.search == "grid":
            raise ValueError("cart.pose: 'search' makes the cart's pose a dimension of a [search]: give a [search] "
                             "table, or pose = 'grid' (every pose of the grid) or 'given'")
        why = cart_does_not_carry(self, self.cart.model)
        if why and self.search == "grid":
            raise ValueError(f"cart.model: '{self.cart.model}' carries the {PLATFORMS[self.cart.model].title} PSMs and "
                             f"ECM, {why}")
        cart_named(self.cart.model).check(self)
        if self.search != "grid" and self.robot.docking_range_deg > 0:
            raise ValueError("cart.model: the setup joints are solved for the docking frames toward the target's "
                             "centre; a [search] that also tilts the docking (robot.docking_range_deg > 0) with the "
                             "cart is not in yet (set robot.docking_range_deg = 0, or cart.model = 'none')")
        return self

    @model_validator(mode="after")
    def _a_given_layout_names_this_runs_arms_and_landmarks(self):
        g = self.given_layout
        if g is None:
            return self
        if (g.psm3 is not None) != (self.robot.instrument_count == 3):
            raise ValueError(f"given_layout.psm3: {'give' if g.psm3 is None else 'leave out'} PSM3's port with "
                             f"robot.instrument_count = {self.robot.instrument_count}")
        from surgopt.studies.port_place.geometry import landmarks_mm

        names = list(landmarks_mm(self.patient))
        for arm in ("psm1", "psm2", "psm3", "ecm"):
            port = getattr(g, arm)
            if port is not None and port.landmark is not None and port.landmark not in names:
                raise ValueError(f"given_layout.{arm}.landmark: {port.landmark!r} is not a landmark of this patient "
                                 f"({', '.join(names)}; name it in patient.landmarks_mm)")
        return self

    @model_validator(mode="after")
    def _enumerated_rolls_on_the_grid(self):
        if self.robot.docking_rolls_deg and self.search != "grid":
            raise ValueError("robot.docking_rolls_deg enumerates the rolls on the grid: a [search] takes each PSM's "
                             "roll as its own dimension (docking_roll = 'search')")
        return self

    @model_validator(mode="after")
    def _a_searched_roll_has_a_search(self):
        if self.robot.docking_roll == "search" and self.search == "grid":
            raise ValueError("robot.docking_roll: 'search' makes each PSM's roll a dimension of a [search]: give a "
                             "[search] table, or docking_roll = 'given' (docking_roll_deg at every port) or "
                             "'most_reach' (per port, on the grid)")
        return self

    @model_validator(mode="after")
    def _search_objectives_are_columns(self):
        check_objectives(self.search, SEARCH_OBJECTIVES)
        return self

    @model_validator(mode="after")
    def _the_wrist_gives_the_approach_cone(self):
        if self.target.approach_direction is not None:
            bend = math.degrees(instrument_of(self).wrist_bend_rad)
            if self.target.approach_half_angle_deg > bend:
                raise ValueError(f"target.approach_half_angle_deg: {self.target.approach_half_angle_deg:g} deg is "
                                 f"more than the instrument's wrist can bend the jaws from its shaft ({bend:.0f} "
                                 f"deg): no port can give every direction of that cone")
        return self

    @model_validator(mode="after")
    def _the_insertion_reaches_the_least_depth(self):
        r = self.robot
        if r.instrument_serial is not None or r.min_wrist_depth_mm is None:
            return self
        arm = instrument_of(self)
        deepest_mm = (arm.insertion_limits_m[1] + arm.along_shaft_m) * 1000
        if r.min_wrist_depth_mm > deepest_mm:
            raise ValueError(f"robot.min_wrist_depth_mm: {r.min_wrist_depth_mm:g} mm, but {arm.name}'s insertion "
                             f"takes its wrist at most {deepest_mm:.1f} mm past the RCM: no point would be reached")
        return self

    @model_validator(mode="after")
    def _the_scope_inserts_to_its_least_insertion(self):
        r = self.robot
        if r.camera_min_insertion_mm is None:
            return self
        if r.camera_serial is not None:
            raise ValueError("robot.camera_min_insertion_mm goes with an RCM endoscope arm (camera_arm or "
                             "camera_file); a serial arm holds the scope where its own IK can")
        arm = camera_arm_of(self)
        if r.camera_min_insertion_mm > arm.insertion_limits_m[1] * 1000:
            raise ValueError(f"robot.camera_min_insertion_mm: {r.camera_min_insertion_mm:g} mm, but {arm.name}'s "
                             f"insertion ends at {arm.insertion_limits_m[1] * 1000:.0f} mm: no port could hold "
                             f"the scope")
        return self

    def _target_clear_of_organs(self, pts: np.ndarray) -> None:
        """No target point inside an obstacle (its own mesh): every shaft to it would cross that organ."""
        if not any(o.obstacle for o in self.patient.organs.values()) or not all(
                o.mesh_sha256 for o in self.patient.organs.values()):
            return  # none, or a stored config read as stored (its files not read again)
        p = self.patient
        for name, organ in p.organs.items():
            if not organ.obstacle:
                continue
            inside = body_mesh(organ.mesh_file, organ.mesh_sha256, p.mesh_units, tuple(p.mesh_offset_mm)).contains(pts)
            if inside.any():
                raise ValueError(f"patient.organs.{name}: {int(np.count_nonzero(inside)):,} of the target's "
                                 f"{len(pts):,} points lie in it, so every shaft to them would cross it: if the target "
                                 f"is in it, set patient.organs.{name}.obstacle = false; else move the target")

    @model_validator(mode="after")
    def _target_inside_and_ranges_ordered(self):
        for name, (lo, hi) in (("robot.camera_range_mm", self.robot.camera_range_mm),
                               ("constraints.port_to_target_mm", self.constraints.port_to_target_mm),
                               ("constraints.manipulation_angle_deg", self.constraints.manipulation_angle_deg)):
            if not 0 <= lo < hi:
                raise ValueError(f"{name}: [{lo:g}, {hi:g}] must be 0 <= low < high")
        if self.target.shape in ("sphere", "ellipsoid", "box") and shape_grid_count(self.target) > 10 * MAX_TARGET_POINTS:
            # counted before it is built: a box holds all, an ellipsoid about pi/6 of its box's points
            share = 1.0 if self.target.shape == "box" else math.pi / 6
            raise ValueError(f"target: about {shape_grid_count(self.target) * share:,.0f} sample points (at most "
                             f"{MAX_TARGET_POINTS:,}: a larger spacing_mm)")
        pts = target_points_mm(self.target)
        if len(pts) == 0:
            raise ValueError("target: no sample point (a spacing larger than the target)")
        if len(pts) > MAX_TARGET_POINTS:
            raise ValueError(f"target: {len(pts):,} sample points (at most {MAX_TARGET_POINTS:,}: a larger spacing_mm)")
        outside = ~inside_body(pts, self.patient)
        if outside.any():
            p = pts[np.argmax(outside)]
            n = self.patient.dome_exponent
            body = (f"the dome {self.patient.semi_axes_mm} mm over z = 0" + (f", exponent {n:g}" if n != 2 else "")
                    if self.patient.shape == "dome"
                    else f"the mesh {self.patient.mesh_file}")
            raise ValueError(f"target: the point ({p[0]:.0f}, {p[1]:.0f}, {p[2]:.0f}) mm is outside the body "
                             f"({body})")
        self._target_clear_of_organs(pts)
        sites, stages = site_stages(self)
        n, ports = len(sites), self.robot.instrument_count + 1
        if n < ports:
            first = next(i for i, (_, k) in enumerate(stages) if k < ports)  # the filter that left too few
            counts = "; ".join(f"{what}: {k:,}" for what, k in stages[:first + 1])
            raise ValueError(f"patient.port_region: {n} candidate site(s), {ports} ports need at least {ports}; of "
                             f"the {self.patient.port_region.site_spacing_mm:g} mm grid's points, {counts}")
        farthest = float(np.max(np.linalg.norm(sites[:, None, :] - sites[None, :, :], axis=2)))
        if farthest < self.constraints.min_port_spacing_mm:
            raise ValueError(f"constraints.min_port_spacing_mm: {self.constraints.min_port_spacing_mm:g} mm, but no two "
                             f"candidate sites are that far apart (the farthest: {farthest:.0f} mm), so every "
                             f"layout would put ports too close")
        return self


Config = PortPlaceConfig


def cart_does_not_carry(cfg: PortPlaceConfig, model: str) -> str:
    """Why the ``model`` cart cannot dock this config's arms ("" when it can): it carries its own PSMs and ECM
    (its platform's ``instrument_arm`` and ``camera_arm``), and is enumerated with the grid of layouts."""
    r = cfg.robot
    psm, ecm = PLATFORMS[model].instrument_arm, PLATFORMS[model].camera_arm
    if r.instrument_serial or r.instrument_file or r.instrument_arm != psm:
        return (f"not {'a serial arm' if r.instrument_serial else 'an arm from a file' if r.instrument_file else r.instrument_arm} "
                f"(robot.instrument_arm = '{psm}', no instrument_file or instrument_serial)")
    if r.camera_serial or r.camera_file or r.camera_arm != ecm:
        return (f"not {'a serial arm' if r.camera_serial else 'an arm from a file' if r.camera_file else r.camera_arm}"
                f" (robot.camera_arm = '{ecm}', no camera_file or camera_serial)")
    if cfg.search != "grid" and cfg.cart.pose != "search":
        return f"with the grid of layouts, not a [search] (give cart.model = '{model}', or cart.pose = 'search')"
    return ""


def _arm_of(cfg: PortPlaceConfig, role: str):
    """The ``role`` ("instrument", "camera") arm: a serial arm's ``SerialHolder`` (``robot.<role>_serial``), an
    RCM arm from its file (``robot.<role>_file``), or the shipped dVRK arm named (``robot.<role>_arm``)."""
    r = cfg.robot
    serial, file = getattr(r, f"{role}_serial"), getattr(r, f"{role}_file")
    if serial is not None:
        return serial.holder()
    return file.limits() if file else get_model(getattr(r, f"{role}_arm"))


def instrument_of(cfg: PortPlaceConfig):
    """The instrument arm (``_arm_of``)."""
    return _arm_of(cfg, "instrument")


def camera_arm_of(cfg: PortPlaceConfig):
    """The endoscope arm (``_arm_of``)."""
    return _arm_of(cfg, "camera")

