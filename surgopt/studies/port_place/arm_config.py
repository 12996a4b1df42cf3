"""Config of port-place's arms beyond the shipped dVRK ones: an RCM mechanism given as a URDF file or an inline DH
table (``[robot.instrument_file]`` and ``[robot.camera_file]``: resolved and checked at validation,
``robots.rcm_arm.rcm_mechanism``, read once per process), and a serial arm that keeps the RCM in software
(``[robot.instrument_serial]``: rcm-grid's arm section, and where its base stands)."""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import ClassVar, Literal

from pydantic import Field, ValidationInfo, model_validator

from surgopt.config import NOT_IN_KEY, StrictModel
from surgopt.studies.rcm_grid.config import DhRowConfig, Finite, Robot


class RcmDhRow(DhRowConfig):
    """One joint of an RCM arm's inline DH table: rcm-grid's DH row (``DhRowConfig``: lengths in m, angles in
    deg) with no rated speed needed, and a prismatic row's ``lower_m``/``upper_m`` (the insertion range, along d,
    which is then its offset) required, below its upper."""

    speed_required: ClassVar[bool] = False

    @model_validator(mode="after")
    def _insertion_range(self):
        if self.joint == "prismatic" and (self.lower_m is None or self.upper_m is None):
            raise ValueError("a prismatic row needs lower_m and upper_m (the insertion range)")
        lo, hi = (self.lower_deg, self.upper_deg) if self.joint == "revolute" else (self.lower_m, self.upper_m)
        if lo is not None and not lo < hi:
            raise ValueError(f"{'lower_deg' if self.joint == 'revolute' else 'lower_m'} must be < "
                             f"{'upper_deg' if self.joint == 'revolute' else 'upper_m'}")
        return self


class RcmArmFile(StrictModel):
    """An RCM arm from a URDF file or an inline DH table (``[robot.instrument_file]``, ``[robot.camera_file]``):
    its first joints must be yaw, pitch and insertion about a remote centre of motion (``robots.rcm_arm``); the
    reaching point is where the wrist's first axis crosses the shaft, or the tip link's origin."""

    urdf: str | None = Field(None, min_length=1, description="URDF file, relative to the config file (its content "
                             "hash, urdf_sha256, is in the store key, not its path)", json_schema_extra=NOT_IN_KEY)
    urdf_sha256: str | None = Field(None, description="filled in: the URDF's content hash (part of the store key)")
    base_link: str | None = Field(None, min_length=1, description="the link at the RCM's mechanism base")
    tip_link: str | None = Field(None, min_length=1)
    dh: list[RcmDhRow] | None = Field(None, min_length=3, max_length=16)
    dh_convention: Literal["standard", "modified"] = "modified"

    @model_validator(mode="after")
    def _one_source(self, info: ValidationInfo):
        if (self.urdf is None) == (self.dh is None):
            raise ValueError("give urdf or dh (one of them)")
        if self.urdf is None and (self.base_link or self.tip_link):
            raise ValueError("base_link and tip_link go with urdf")
        context = info.context or {}
        if self.urdf is not None:
            from surgopt.files import resolve_and_hash
            from surgopt.robots.chain import MAX_URDF_BYTES

            resolve_and_hash(self, "urdf", "urdf_sha256", MAX_URDF_BYTES, context)
        if not context.get("stored"):
            self.limits()  # read and checked here
        return self

    def limits(self):
        """The arm's ``robots.rcm_arm.RcmLimits`` (a URDF parsed once per file content: ``chain.urdf_chain``)."""
        from surgopt.robots import chain
        from surgopt.robots.rcm_arm import rcm_mechanism

        if self.urdf is not None:
            spec = chain.urdf_chain(self.urdf, self.urdf_sha256, self.base_link, self.tip_link)
            name, source = Path(self.urdf).stem, f"{self.urdf} (sha256 {(self.urdf_sha256 or '?')[:12]})"
        else:
            spec = chain.from_dh([r.row(i) for i, r in enumerate(self.dh)], self.dh_convention)
            name, source = "dh", f"inline {self.dh_convention} DH table"
        return rcm_mechanism(spec, name, source, "urdf" if self.urdf is not None else "dh")


@dataclass(frozen=True)
class SerialHolder:
    """What port-place reads of a serial instrument arm beside its chain (the names ``dvrk.RcmArm`` has)."""

    name: str
    source: str
    wrist_bend_rad: float


class SerialInstrumentArm(Robot):
    """A serial arm holding the instrument and keeping its remote centre of motion at the port in software (the
    PA10-7C of Locke & Patel, a UR5e, a Panda, an LBR iiwa, any DH table or URDF: rcm-grid's ``[robot]`` fields,
    docs/robots.md), in place of an RCM mechanism. Its base stands so that ``rcm_in_base_m`` (where it keeps the
    RCM, in its base frame: an rcm-grid optimum) is the port, its z axis up, turned about the vertical so that
    the RCM lies radially inward of the base (the arm beside the patient, reaching in), then by
    ``base_yaw_deg``."""

    rcm_in_base_m: list[Finite] = Field(..., min_length=3, max_length=3,
                                        description="the RCM in the arm's base frame (m): where rcm-grid puts it")
    base_yaw_deg: float = Field(0.0, ge=-180.0, le=180.0, description="the base turned about the port's vertical "
                                                                      "off the radial stance (deg)")
    wrist_bend_deg: float = Field(0.0, ge=0.0, le=90.0, description="how far the held instrument's wrist bends the "
                                                                   "jaws off its shaft (deg; 0: a straight tool)")
    stance_range_m: float = Field(0.0, ge=0.0, le=0.5, description="a [search] may move the RCM this far (m) "
                                  "out from the base and up or down, off rcm_in_base_m: where the arm stands is "
                                  "then searched with the ports; 0: fixed")
    link_radius_mm: float = Field(60.0, ge=0.0, le=300.0, description="the links as capsules of this radius about "
                                  "their centre lines (base to flange): a port is refused when, docked there, they "
                                  "come nearer the body than this (assumption: 60 mm, a PA10/UR5e-sized link)")

    @model_validator(mode="after")
    def _rcm_beside_the_base(self):
        r = self.rcm_in_base_m
        if math.hypot(r[0], r[1]) < 0.05 or math.hypot(*r) > 3.0:
            raise ValueError(f"rcm_in_base_m: {list(r)} m; the RCM must lie 0.05 m or more from the base's vertical "
                             f"axis (the base stands beside the port) and within 3 m of it")
        return self

    def holder(self) -> SerialHolder:
        if self.urdf is not None:
            name, source = Path(self.urdf).stem, f"{self.urdf} (sha256 {(self.urdf_sha256 or '?')[:12]})"
        elif self.dh is not None:
            name, source = "dh", f"inline {self.dh_convention} DH table"
        else:
            name, source = self.model, f"shipped model {self.model}"
        return SerialHolder(f"{name} (software RCM)", source, math.radians(self.wrist_bend_deg))
