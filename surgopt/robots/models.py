"""The shipped arm models for the RCM study, as data: each model file defines ``MODEL = ArmModel(...)``.

``MODELS`` names them (``robot.model`` in a config, ``--robot NAME``). A model carries its DH table
(every number with its source in the model file), the joints it locks and why, a seed configuration
on the wanted IK branch, and a tool, workspace and candidate grid that make ``surgopt rcm-grid
--robot NAME`` a meaningful study out of the box (docs/robots.md).
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass, field

from surgopt.robots.chain import DhRow

#: robot.model -> module defining MODEL.
MODELS = {"pa10_7c": "surgopt.robots.pa10_7c", "ur5e": "surgopt.robots.ur5e", "panda": "surgopt.robots.panda",
          "lbr_iiwa_14": "surgopt.robots.lbr_iiwa_14"}

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


def get_model(name: str) -> ArmModel:
    """The shipped model of that name (``KeyError`` for an unknown one)."""
    return importlib.import_module(MODELS[name]).MODEL
