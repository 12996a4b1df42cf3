"""Config of an RCM arm given as a URDF file or an inline DH table (port-place's ``[robot.instrument_file]`` and
``[robot.camera_file]``): resolved and checked at validation (``robots.rcm_arm.rcm_mechanism``), read once per
process."""
from __future__ import annotations

from functools import lru_cache
from pathlib import Path
from typing import Annotated, Literal

from pydantic import Field, ValidationInfo, model_validator

from surgopt.config import NOT_IN_KEY, StrictModel


class RcmDhRow(StrictModel):
    """One joint of an RCM arm's inline DH table: lengths in m, angles in deg; a revolute row's range
    ``lower_deg``/``upper_deg`` (both left out: one turn), a prismatic row's ``lower_m``/``upper_m`` (it slides
    along d, which is then its offset)."""

    name: str | None = Field(None, min_length=1, max_length=64)
    joint: Literal["revolute", "prismatic"] = "revolute"
    a_m: Annotated[float, Field(ge=-10, le=10)]
    alpha_deg: Annotated[float, Field(ge=-360, le=360)]
    d_m: Annotated[float, Field(ge=-10, le=10)]
    theta_offset_deg: Annotated[float, Field(ge=-360, le=360)] = 0.0
    lower_deg: Annotated[float, Field(ge=-720, le=720)] | None = None
    upper_deg: Annotated[float, Field(ge=-720, le=720)] | None = None
    lower_m: Annotated[float, Field(ge=-10, le=10)] | None = None
    upper_m: Annotated[float, Field(ge=-10, le=10)] | None = None

    @model_validator(mode="after")
    def _limits_of_its_kind(self):
        rev = self.joint == "revolute"
        lo, hi = ("lower_deg", "upper_deg") if rev else ("lower_m", "upper_m")
        wrong = [f for f in (("lower_m", "upper_m") if rev else ("lower_deg", "upper_deg")) if getattr(self, f) is not None]
        if wrong:
            raise ValueError(f"a {self.joint} row takes {lo} and {hi}, not {', '.join(wrong)}")
        if not rev and (self.lower_m is None or self.upper_m is None):
            raise ValueError("a prismatic row needs lower_m and upper_m (the insertion range)")
        if (getattr(self, lo) is None) != (getattr(self, hi) is None):
            raise ValueError(f"give both {lo} and {hi}, or neither")
        if getattr(self, lo) is not None and not getattr(self, lo) < getattr(self, hi):
            raise ValueError(f"{lo} must be < {hi}")
        return self

    def row(self, index: int):
        from surgopt.robots.chain import DhRow

        rev = self.joint == "revolute"
        return DhRow(self.a_m, self.alpha_deg, self.d_m, self.theta_offset_deg,
                     self.lower_deg if rev else self.lower_m, self.upper_deg if rev else self.upper_m, 1.0,
                     self.name or f"j{index + 1}", not rev)


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
            from surgopt.files import config_file_path, hashed_config_file
            from surgopt.robots.chain import MAX_URDF_BYTES

            path = config_file_path(self.urdf, context)
            object.__setattr__(self, "urdf", str(path))
            if not context.get("stored"):
                _, sha = hashed_config_file("urdf", path, self.urdf_sha256, MAX_URDF_BYTES, "urdf_sha256")
                object.__setattr__(self, "urdf_sha256", sha)
        if not context.get("stored"):
            file_arm(self.model_dump_json())  # read and checked once here
        return self


@lru_cache(maxsize=8)
def file_arm(arm_json: str):
    """The ``robots.rcm_arm.RcmLimits`` of an ``RcmArmFile`` (its JSON), read once per process."""
    from surgopt.robots import chain
    from surgopt.robots.rcm_arm import rcm_mechanism

    a = RcmArmFile.model_validate_json(arm_json, context={"stored": True})
    if a.urdf is not None:
        spec = chain.from_urdf(a.urdf, a.base_link, a.tip_link, {})
        name, source = Path(a.urdf).stem, f"{a.urdf} (sha256 {a.urdf_sha256[:12] if a.urdf_sha256 else '?'})"
    else:
        spec = chain.from_dh([r.row(i) for i, r in enumerate(a.dh)], a.dh_convention)
        name, source = "dh", f"inline {a.dh_convention} DH table"
    return rcm_mechanism(spec, name, source, "urdf" if a.urdf is not None else "dh")
