"""The shipped arms, as data, in one registry (``ARMS``): each model file defines ``MODEL``.

An arm is of one of two kinds. A *serial* arm (``ArmModel``: a PA10, a UR5e, ...) keeps a remote centre of motion
in software; ``MODELS`` names them (``robot.model`` in rcm-grid, ``--robot NAME``, a serial arm holding
port-place's instruments). An *RCM* arm (``dvrk.RcmArm``: the dVRK's PSMs and ECMs) is a mechanism whose first
joints pivot about the RCM; it holds an instrument or the endoscope (``INSTRUMENT_ARMS``, ``CAMERA_ARMS``:
port-place's ``robot.instrument_arm`` / ``robot.camera_arm``). The three lists are derived from ``ARMS``.

A serial model carries its DH table (every number with its source in the model file), the joints it locks and
why, a seed configuration on the wanted IK branch, and a tool, workspace and candidate grid that make
``surgopt rcm-grid --robot NAME`` a meaningful study out of the box (docs/robots.md).
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass, field
from typing import NamedTuple

from surgopt.robots.chain import DhRow


class Arm(NamedTuple):
    """A registry entry: the arm's kind ("serial" | "rcm"), what an RCM arm holds ("instrument" | "camera"; None
    for a serial arm, which can hold either) and the module defining its ``MODEL``."""

    kind: str
    holds: str | None
    module: str


#: Every shipped arm: name -> entry (the one list; the ones below are read from it).
ARMS = {
    "pa10_7c": Arm("serial", None, "surgopt.robots.pa10_7c"),
    "ur5e": Arm("serial", None, "surgopt.robots.ur5e"),
    "panda": Arm("serial", None, "surgopt.robots.panda"),
    "lbr_iiwa_14": Arm("serial", None, "surgopt.robots.lbr_iiwa_14"),
    "dvrk_psm_classic": Arm("rcm", "instrument", "surgopt.robots.dvrk.psm_classic"),
    "dvrk_psm_si": Arm("rcm", "instrument", "surgopt.robots.dvrk.psm_si"),
    "dvrk_ecm_classic": Arm("rcm", "camera", "surgopt.robots.dvrk.ecm_classic"),
    "dvrk_ecm_si": Arm("rcm", "camera", "surgopt.robots.dvrk.ecm_si"),
}


def arm_names(kind: str, holds: str | None = None) -> tuple[str, ...]:
    """The names of the shipped arms of a kind (and, for RCM arms, of what they hold), in registry order."""
    return tuple(n for n, a in ARMS.items() if a.kind == kind and (holds is None or a.holds == holds))


#: Serial arms (``robot.model``); RCM arms holding an instrument, and the endoscope.
MODELS = arm_names("serial")
INSTRUMENT_ARMS = arm_names("rcm", "instrument")
CAMERA_ARMS = arm_names("rcm", "camera")

#: The paper's workspace (Locke & Patel Sec. III-B), the shipped models' default: a 50 mm cube of
#: 17^3 tool tips centred 100 mm below the RCM.
PAPER_WORKSPACE = {"cube_side_m": 0.05, "depth_below_rcm_m": 0.1, "points_per_side": 17}


@dataclass(frozen=True)
class ArmModel:
    """A shipped arm: DH rows, convention, defaults for the RCM study (angles in degrees, lengths in m)."""

    name: str
    title: str
    convention: str
    dh: tuple[DhRow, ...]
    locked_joints_deg: dict[str, float]
    lock_reason: str
    seed_deg: dict[str, float]
    tool_length_m: float
    #: workspace defaults: cube_side_m, depth_below_rcm_m, points_per_side
    workspace: dict = field(default_factory=dict)
    #: candidate grid defaults (candidates.grid fields), in the base frame
    grid: dict = field(default_factory=dict)
    z_reference: str = "base"
    #: the locked joint that only spins the tool about its own axis (the standard Jacobian's sixth joint)
    spin_joint: str | None = None

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(r.name for r in self.dh)


def get_model(name: str):
    """The shipped arm of that name: an ``ArmModel`` (serial) or a ``dvrk.RcmArm`` (``KeyError`` for an unknown
    one)."""
    return importlib.import_module(ARMS[name].module).MODEL
