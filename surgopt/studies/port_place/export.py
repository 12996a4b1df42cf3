"""port-place's own export formats (``surgopt export KEY --design ID --format dvrk``): one layout's set-up as
the dVRK reads it: where the cart stands, each setup joint's values in the order and units of the dVRK's
``simulated_position`` (the column in m, then rad), the transforms they were solved with, each port, and each
arm's own joints when its instrument points at the target's centre."""
from __future__ import annotations

import json

import numpy as np

from surgopt.robots.dvrk.links import LINK_MODEL_WORDS
from surgopt.robots.dvrk.platforms import CAMERA_ROLE, INSTRUMENT_ROLES, PLATFORMS, role_of

from surgopt.errors import UsageError
from surgopt.studies.port_place.carts import has_cart
from surgopt.studies.port_place.config import PortPlaceConfig, camera_arm_of, instrument_of
from surgopt.studies.port_place.geometry import FRAME_TEXT
from surgopt.studies.port_place.hands import pairing_words, teleop_pairing

#: The format's version: a reader can refuse one it does not know.
DVRK_FORMAT = "surgopt-dvrk-setup-1"


def _matrix(t) -> list:
    return [[float(v) for v in row] for row in np.asarray(t, float)]


def clearances_of(checks: list, cfg: PortPlaceConfig) -> dict:
    """The layout's least clearances outside the body (``clashes``): each check's value (mm), links and where,
    and the least of them; the link model named (``robots/dvrk/links.LINK_MODEL_WORDS``)."""
    from surgopt.studies.port_place.clashes import in_feasible, least

    worst = least(checks)
    model = f"{LINK_MODEL_WORDS} (robots/dvrk/links.py); {in_feasible(cfg)}"
    return {"least_mm": None if worst is None else round(worst.clearance_mm, 1),
            "model": model,
            "checks": [{"check": c.check, "clearance_mm": round(c.clearance_mm, 1), "link": c.link_a,
                        "against": c.link_b, "where": c.where} for c in checks]}


def fails_on(bits: int) -> list[str]:
    """What a row fails on (``reasons.REASONS``, in their order); empty for a feasible row."""
    from surgopt.kinematics.port.reasons import REASONS

    return [text for bit, text in REASONS.items() if bits & bit]


def refuse_undocked(fmt: str, cfg: PortPlaceConfig, row: dict) -> None:
    """A robot's format needs the cart's docking: a run without the cart, or a design no cart pose docks, is
    refused in one line naming the format."""
    if not has_cart(cfg):
        raise UsageError(f"--format {fmt}: this run has no cart (cart.model = 'none'): run it with [cart] model = "
                         "'classic' (or 'si') to solve the setup joints")
    if row.get("cart_pose", -1) < 0:
        raise UsageError(f"--format {fmt}: design {row['design_id']} is not dockable (no cart pose of the grid "
                         f"docks every arm); export a design whose cart_pose >= 0")


def dvrk_setup(cfg: PortPlaceConfig, row: dict) -> str:
    """The layout of ``row`` (a design of a run with the cart) as JSON: ``cart_to_patient`` (the patient's frame
    in the cart's world frame, 4x4, m), whether the row is feasible (and what it fails on), and one entry per arm
    (PSM1, PSM2, PSM3, ECM): its cart ("classic" or "si"), SUJ joints, ``world_origin_to_suj`` and
    ``suj_tip_to_tool_origin`` as used, its port (mm, patient frame), its base (RCM) frame in the cart's world
    frame, and its own joints at the target's centre."""
    from surgopt.studies.port_place.layout import arm_joints_at_centre, layout_of
    from surgopt.studies.port_place.rolls import model_for
    from surgopt.studies.port_place.tables import camera_tips

    refuse_undocked("dvrk", cfg, row)
    centre = np.asarray(cfg.target.centre_mm, float) / 1000
    model = model_for(cfg, row)  # (with rolls enumerated: its roll's)
    layout = layout_of(model, row)
    patient = layout.patient_in_cart
    arms = []
    docked, rolls, docking, clearances = layout.docked, layout.rolls, layout.docking, layout.clearances
    for a in docked:
        suj = PLATFORMS[cfg.cart.model].suj(a.arm)
        holder = camera_arm_of(cfg) if a.arm == "ECM" else instrument_of(cfg)
        port = np.asarray(a.port_m)
        if a.arm == "ECM":  # its own yaw and pitch aim the scope; inserted as the rows hold it (camera_views)
            depth = (row["ecm_tip_depth_mm"] if "ecm_tip_depth_mm" in row  # as the row holds it; a run stored
                     else camera_tips(model, port[None])["camera_tip_depth_mm"][0]) / 1000  # before: solved
            joints = [*a.ecm, depth - holder.along_shaft_m] if a.ecm and np.isfinite(depth) else None
        else:
            joints = arm_joints_at_centre(model.limits, np.linalg.inv(patient) @ a.base, centre)
        arms.append({
            "name": a.arm, "suj": cfg.cart.model,
            "suj_joints": list(a.joints) if a.joints else None,
            "suj_least_range_margin": a.margin, "suj_tightest_joint": a.tightest or None, "note": a.note or None,
            "world_origin_to_suj": _matrix(suj.world_to_suj), "suj_tip_to_tool_origin": _matrix(suj.tip_to_tool),
            "port_mm": [float(v) * 1000 for v in port],
            "port_from_landmark": port_from_landmark(cfg, port * 1000),
            "base_in_cart": None if a.base is None else _matrix(a.base),
            "docking_roll_deg": a.roll_deg,
            "arm": holder.name,
            "arm_joints_at_target_centre": joints,
        })
    out = {"format": DVRK_FORMAT, "run_key": row.get("run_key"), "design_id": row["design_id"],
           "units": f"metres and radians (the SUJ column in metres); port_mm in millimetres, in the {FRAME_TEXT}",
           "cart": {"model": cfg.cart.model, "x_mm": row["cart_x_mm"], "y_mm": row["cart_y_mm"],
                    "heading_deg": row["cart_heading_deg"], "table_height_mm": cfg.cart.table_height_mm,
                    "trendelenburg_deg": cfg.cart.trendelenburg_deg, "lateral_tilt_deg": cfg.cart.lateral_tilt_deg},
           "feasible": bool(row["feasible"]), "fails_on": fails_on(row["infeasible"]),
           "cart_to_patient": _matrix(patient), "docking": docking, "arms": arms,
           "teleop": teleop_pairing(int(row.get("image_right_psm", 0))),
           "teleop_note": (f"{pairing_words(int(row['image_right_psm']))}: MTMR drives the PSM on the camera "
                           f"image's right (the image level, its up the patient's front)" if "image_right_psm" in row
                           else "a run stored before the rows said which PSM is on the image's right: run it again"),
           "clearances_outside_body": clearances_of(clearances, cfg),
           "clearances_over_whole_target": whole_target_of(model, row, rolls)}
    return json.dumps(out, indent=1) + "\n"


def whole_target_of(model, row: dict, rolls: dict) -> dict:
    """(#54 item 3) The layout's arms pair by pair over every target point (``clashes.whole_target_clearances``),
    at the row's own docking: the sampled ``clearances_outside_body`` may miss an overlap between their points.
    Where the export docks otherwise (rolled to clear), not checked, and said."""
    from surgopt.studies.port_place.clashes import least, whole_target_clearances

    if any(rolls.values()):
        return {"least_mm": None, "note": "not checked: the export docks the PSMs rolled, the check is of the "
                                          "row's own docking", "checks": []}
    checks = whole_target_clearances(model, row)
    worst = least(checks)
    return {"least_mm": None if worst is None else round(worst.clearance_mm, 1),
            "checks": [{"check": c.check, "clearance_mm": round(c.clearance_mm, 1), "link": c.link_a,
                        "against": c.link_b, "where": c.where} for c in checks]}


#: The arms the dVRK's SUJ_Fixed reads, all four of them (``mtsIntuitiveResearchKitSUJFixed::Configure`` refuses
#: any other count or name): the platform registry's roles, the camera's first as the dVRK's sample file has it.
SUJ_FIXED_ARMS = (CAMERA_ROLE, *INSTRUMENT_ROLES)


def suj_fixed(cfg: PortPlaceConfig, row: dict) -> str:
    """(#57 item 5) The dVRK's own ``SUJ_Fixed`` file for one layout (as jhu-dvrk/sawIntuitiveResearchKit's
    ``share/arm/suj-fixed-simulated.json``): ``"arms"``, the four the dVRK expects, each ``"name"`` and
    ``"measured_cp"``, the arm's base frame in the cart's frame (4x4, m), docked as ``--format dvrk`` docks it (the
    setup joints' forward kinematics at the joints it writes). An arm the layout does not place (PSM3 of a two-PSM
    layout, or one its setup joints do not reach) has no ``measured_cp``: the dVRK then warns and leaves it
    invalid, rather than holding a frame no one chose. A comment at the top (the dVRK's JSON reader takes them)
    names the run, the design and the teleoperation pairing that keeps the surgeon's hands uncrossed."""
    from surgopt.studies.port_place.layout import layout_of
    from surgopt.studies.port_place.rolls import model_for

    refuse_undocked("dvrk-suj-fixed", cfg, row)
    layout = layout_of(model_for(cfg, row), row)
    docking, frames = layout.docking, layout.frames_of()
    arms = []
    for name in SUJ_FIXED_ARMS:
        arm = {"name": name}
        if name in frames:
            arm["measured_cp"] = _matrix(frames[name])
        arms.append(arm)
    pairing = teleop_pairing(int(row.get("image_right_psm", 0)))
    said = (f"surgopt port-place: run {row.get('run_key') or '?'}, design {row['design_id']} (feasible: "
            f"{bool(row['feasible'])}); each measured_cp is the arm's base (RCM) frame in the cart's frame, m; "
            f"docking: {docking}; an arm without measured_cp is not placed by this layout; the teleoperation that "
            f"keeps the surgeon's hands uncrossed: "
            + (", ".join(f"{m} drives {p}" for m, p in pairing.items()) or "not known (a run stored before the rows "
                                                                           "said which PSM is on the image's right)"))
    return f"/* {said.replace('*/', '* /')} */\n" + json.dumps({"arms": arms}, indent=4) + "\n"


#: The SUJ_Fixed file the console file names, beside it (``--format dvrk-suj-fixed --out`` this name).
CONSOLE_SUJ_FILE = "suj-fixed.json"


def dvrk_console(cfg: PortPlaceConfig, row: dict) -> str:
    """(#57 item 5) The dVRK console file that loads one layout's SUJ_Fixed file (as sawIntuitiveResearchKit's
    ``share/console/console-patient-cart-fixed-simulated.json`` and ``console-full-system-simulated.json``): the
    ``SUJ_Fixed`` component reading ``CONSOLE_SUJ_FILE`` beside it, each arm the layout places with its base frame
    from that component's interface of its name, the two MTMs, ``psm_teleops`` with the pairing that keeps the
    surgeon's hands uncrossed (MTMR drives the PSM on the camera image's right) and ``ecm_teleop``. The arm files are
    the dVRK's simulated kinematics (``Platform.console_arm_files``); a real system names its own, as the comment at
    the top says."""
    from surgopt.studies.port_place.layout import layout_of
    from surgopt.studies.port_place.rolls import model_for

    refuse_undocked("dvrk-console", cfg, row)
    frames = layout_of(model_for(cfg, row), row).frames_of()
    psm_file, ecm_file = PLATFORMS[cfg.cart.model].console_arm_files
    arms = [{"name": "MTML", "type": "MTM", "simulation": "KINEMATIC", "arm": "arm/MTML_KIN_SIMULATED.json"},
            {"name": "MTMR", "type": "MTM", "simulation": "KINEMATIC", "arm": "arm/MTMR_KIN_SIMULATED.json"},
            {"name": "SUJ", "type": "SUJ_Fixed", "kinematic": CONSOLE_SUJ_FILE}]
    for name in (*INSTRUMENT_ROLES, CAMERA_ROLE):
        if name in frames:
            arms.append({"name": name, "type": "ECM" if name == CAMERA_ROLE else "PSM", "simulation": "KINEMATIC",
                         "arm": ecm_file if name == CAMERA_ROLE else psm_file,
                         "base_frame": {"component": "SUJ", "interface": name}})
    pairing = teleop_pairing(int(row.get("image_right_psm", 0))) or {"MTMR": "PSM1", "MTML": "PSM2"}
    doc = {"arms": arms, "psm_teleops": [{"mtm": m, "psm": p} for m, p in pairing.items() if p in frames]}
    if CAMERA_ROLE in frames:
        doc["ecm_teleop"] = {"mtm_left": "MTML", "mtm_right": "MTMR", "ecm": CAMERA_ROLE}
    said = (f"surgopt port-place: run {row.get('run_key') or '?'}, design {row['design_id']}: the dVRK console for "
            f"this layout, reading the SUJ_Fixed file {CONSOLE_SUJ_FILE} beside it (surgopt export ... --format "
            f"dvrk-suj-fixed --out {CONSOLE_SUJ_FILE}); "
            + ("MTMR drives the PSM on the camera image's right, so the surgeon's hands are not crossed; "
               if teleop_pairing(int(row.get("image_right_psm", 0))) else
               "the console's default pairing (the run did not say which PSM is on the image's right); ")
            + "the arm files are the dVRK's simulated kinematics: a real system names its own calibrated files")
    return f"/* {said.replace('*/', '* /')} */\n" + json.dumps(doc, indent=4) + "\n"


def ports_csv(cfg: PortPlaceConfig, row: dict) -> str:
    """``surgopt export KEY --design ID --format ports``: the layout's ports and the patient's landmarks as CSV, one
    line each: what (port, landmark), name, site, x_mm, y_mm, z_mm (the patient frame; a landmark's z is the
    body's wall over it, blank where there is none), and each one's top-view offset from the reference landmark,
    left_mm (the patient's left +) and cranial_mm (toward the head +), with the same in words; and the same along
    the skin (``geometry.along_skin_mm``: across at the landmark's level, then along the body, as a tape measures)."""
    import csv
    import io

    from surgopt.studies.port_place.geometry import (along_skin_mm, from_landmark, landmarks_mm, reference_landmark,
                                                     skin_words, wall_height_mm)

    name, mark = reference_landmark(cfg.patient)
    out = io.StringIO()
    w = csv.writer(out, lineterminator="\n")
    w.writerow(["what", "name", "site", "x_mm", "y_mm", "z_mm", f"left_of_{name}_mm", f"cranial_of_{name}_mm",
                f"from_{name}", f"left_of_{name}_along_skin_mm", f"cranial_of_{name}_along_skin_mm",
                f"from_{name}_along_skin"])

    def line(what, label, site, x, y, z):
        across, along = along_skin_mm(cfg.patient, mark, x, y)
        w.writerow([what, label, site, f"{x:.1f}", f"{y:.1f}", "" if not np.isfinite(z) else f"{z:.1f}",
                    f"{x - mark[0]:.1f}", f"{y - mark[1]:.1f}", from_landmark(x, y, mark), f"{across:.1f}",
                    f"{along:.1f}", skin_words(cfg.patient, mark, x, y)])

    for arm in ("psm1", "psm2", "psm3", "ecm"):
        if f"{arm}_site" in row:
            line("port", role_of(arm), row[f"{arm}_site"], row[f"{arm}_x_mm"], row[f"{arm}_y_mm"], row[f"{arm}_z_mm"])
    for label, (x, y) in landmarks_mm(cfg.patient).items():
        z = float(wall_height_mm(np.array([x]), np.array([y]), cfg.patient)[0])
        line("landmark", label, "", x, y, z)
    return out.getvalue()



#: The markups schema a 3D Slicer markups file names (Slicer's own writer's, vtkMRMLMarkupsJsonStorageNode.cxx;
#: its reader accepts any 1.x.y).
SLICER_MARKUPS_SCHEMA = ("https://raw.githubusercontent.com/slicer/slicer/master/Modules/Loadable/Markups/Resources/"
                         "Schema/markups-schema-v1.0.3.json#")


def to_lps_mm(cfg: PortPlaceConfig, p_mm) -> list[float]:
    """A point of the patient frame (mm: x the patient's left, y toward the head, z anterior) in LPS (x the patient's
    left, y posterior, z superior), the frame a CT's DICOM series and 3D Slicer's files use; for a mesh patient in the
    mesh file's own frame (``patient.mesh_offset_mm`` taken off), so the points land on the mesh loaded beside them."""
    x, y, z = (np.asarray(p_mm, float) - (np.asarray(cfg.patient.mesh_offset_mm, float) if cfg.patient.shape == "mesh"
                                          else 0.0))
    return [float(x), float(-z), float(y)]


def port_from_landmark(cfg: PortPlaceConfig, port_mm) -> dict:
    """(#57 item 2) Where a port lies from the reference landmark, as a surgeon marks it: the top view's offsets and
    the distances along the skin (``geometry.along_skin_mm``: across at the landmark's level, then along the body),
    mm, signed left + and cranial +, with both in words."""
    from surgopt.studies.port_place.geometry import along_skin_mm, from_landmark, reference_landmark, skin_words

    name, mark = reference_landmark(cfg.patient)
    x, y = float(port_mm[0]), float(port_mm[1])
    across, along = along_skin_mm(cfg.patient, mark, x, y)
    return {"landmark": name, "left_mm": round(x - mark[0], 1), "cranial_mm": round(y - mark[1], 1),
            "top_view": from_landmark(x, y, mark), "left_along_skin_mm": round(across, 1),
            "cranial_along_skin_mm": round(along, 1), "along_skin": skin_words(cfg.patient, mark, x, y)}


def slicer_markups(cfg: PortPlaceConfig, row: dict) -> str:
    """(#57 item 5) One layout as a 3D Slicer markups file (``.mrk.json``, Slicer's markups schema v1.0.3): two point
    lists in LPS, mm: the ports (PSM1, PSM2, (PSM3,) ECM, each with its site and its position from the reference
    landmark in words) and the patient's landmarks (on the body's surface above their top-view points)."""
    from surgopt.robots.dvrk.platforms import role_of
    from surgopt.studies.port_place.columns import arms_of
    from surgopt.studies.port_place.geometry import (from_landmark, landmarks_mm, reference_landmark, skin_words,
                                                     wall_height_mm)

    mark_name, mark = reference_landmark(cfg.patient)

    def point(i: int, label: str, p_mm, description: str) -> dict:
        return {"id": str(i + 1), "label": label, "description": description, "associatedNodeID": "",
                "position": to_lps_mm(cfg, p_mm), "orientation": [-1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 1.0],
                "selected": True, "locked": True, "visibility": True, "positionStatus": "defined"}

    ports = [point(i, role_of(a), [row[f"{a}_{c}_mm"] for c in "xyz"],
                   f"site {row[f'{a}_site']}; {from_landmark(row[f'{a}_x_mm'], row[f'{a}_y_mm'], mark)} of the "
                   f"{mark_name} (mm, top view); "
                   f"{skin_words(cfg.patient, mark, row[f'{a}_x_mm'], row[f'{a}_y_mm'])} along the skin")
             for i, a in enumerate(arms_of(cfg))]
    names = list(landmarks_mm(cfg.patient).items())
    xs, ys = np.array([p[0] for _, p in names], float), np.array([p[1] for _, p in names], float)
    heights = np.nan_to_num(wall_height_mm(xs, ys, cfg.patient), nan=0.0)  # off the body: on the table top
    marks = [point(i, name, (x, y, z), "a landmark (top view as given; on the body's surface)")
             for i, ((name, _), x, y, z) in enumerate(zip(names, xs, ys, heights))]

    def markup(name: str, points: list, colour: list) -> dict:
        return {"type": "Fiducial", "name": name, "coordinateSystem": "LPS", "coordinateUnits": "mm",
                "locked": True, "fixedNumberOfControlPoints": True, "labelFormat": "%N-%d", "controlPoints": points,
                "display": {"visibility": True, "color": colour, "selectedColor": colour,
                            "pointLabelsVisibility": True, "glyphType": "Sphere3D", "glyphScale": 2.0}}

    doc = {"@schema": SLICER_MARKUPS_SCHEMA,
           "markups": [markup(f"surgopt ports, design {row['design_id']}", ports, [0.9, 0.2, 0.2]),
                       markup("surgopt landmarks", marks, [0.2, 0.5, 0.9])]}
    return json.dumps(doc, indent=1) + "\n"
