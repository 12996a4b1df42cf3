"""#57 item 5: `export --format slicer`, a 3D Slicer markups file of one layout: it validates against Slicer's
published markups schema (tests/data/slicer_markups_schema_v1.0.3.json: Slicer/Slicer at 583e9b37d5,
Modules/Loadable/Markups/Resources/Schema/markups-schema-v1.0.3.json, sha256 8b852fa2...), its @schema is one
Slicer's reader accepts (its ACCEPTED_MARKUPS_SCHEMA_REGEX, vtkMRMLMarkupsJsonStorageNode.cxx), and its points
round-trip: each port and landmark read back from LPS into the patient frame equals the row's (0.01 mm)."""
import json
import re
from pathlib import Path

import jsonschema
import numpy as np
import pytest

from surgopt.studies.port_place import config as C
from surgopt.studies.port_place import export as E
from surgopt.studies.port_place import study as S
from surgopt.studies.port_place.geometry import landmarks_mm

SCHEMA = Path(__file__).parent / "data" / "slicer_markups_schema_v1.0.3.json"
MESH = Path(__file__).parent / "baselines" / "port_variants" / "lopsided_dome.stl"
#: vtkMRMLMarkupsJsonStorageNode.cxx (Slicer 583e9b37d5): the @schema values its reader accepts.
ACCEPTED = r".*markups-schema-v1\.[0-9]+\.[0-9]+\.json#*$"
SMALL = {"patient": {"port_region": {"site_spacing_mm": 36.0}}, "target": {"spacing_mm": 15.0},
         "cart": {"model": "none"}}


def _from_lps(p):
    """LPS (x to the patient's left, y posterior, z superior) back into surgopt's patient frame (x left, y toward
    the head, z anterior): written out here apart from the export."""
    x, y, z = p
    return np.array([x, z, -y])


@pytest.mark.parametrize("mesh", [False, True])
def test_the_slicer_markups_validate_and_round_trip_the_ports_and_landmarks(mesh, tmp_path):
    """On the dome, and on a mesh patient moved by ``mesh_offset_mm`` (its points then in the mesh file's own frame,
    the offset taken off, so they land on the mesh loaded beside them)."""
    offset = np.array([12.5, -30.0, 7.0]) if mesh else np.zeros(3)
    given = {**SMALL, "patient": {**SMALL["patient"], "shape": "mesh", "mesh_file": str(MESH),
                                  "mesh_offset_mm": offset.tolist(), "port_region": {"site_spacing_mm": 72.0}}} \
        if mesh else SMALL
    cfg = C.PortPlaceConfig.model_validate(given)
    cols = S.compute_task(cfg, S.n_total(cfg), 0)
    r = int(np.flatnonzero(cols["feasible"])[0])
    row = {c: v[r].item() if hasattr(v[r], "item") else v[r] for c, v in cols.items()}
    doc = json.loads(E.slicer_markups(cfg, row))
    jsonschema.validate(doc, json.loads(SCHEMA.read_text()))
    assert re.match(ACCEPTED, doc["@schema"].lower())
    ports, marks = doc["markups"]
    assert ports["coordinateSystem"] == marks["coordinateSystem"] == "LPS" and ports["coordinateUnits"] == "mm"
    got = {p["label"]: _from_lps(p["position"]) + offset for p in ports["controlPoints"]}
    assert set(got) == {"PSM1", "PSM2", "ECM"}
    for arm in ("psm1", "psm2", "ecm"):
        np.testing.assert_allclose(got[arm.upper()], [row[f"{arm}_{c}_mm"] for c in "xyz"], atol=0.01)
    lm = {p["label"]: _from_lps(p["position"]) + offset for p in marks["controlPoints"]}
    for name, (x, y) in landmarks_mm(cfg.patient).items():
        np.testing.assert_allclose(lm[name][:2], [x, y], atol=0.01)
