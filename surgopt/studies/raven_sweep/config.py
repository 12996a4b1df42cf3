"""Config models of the raven-sweep study: the Table II sweep, the geometry the paper leaves open,
the refine search. Every field has its unit in its name; docs/reproduction.md says why each default."""
from __future__ import annotations

import math
from typing import Annotated, Literal, Union

from pydantic import BeforeValidator, Discriminator, Field, Tag, field_validator, model_validator

from surgopt.config import StrictModel
from surgopt.robots import raven_iv
from surgopt.plans.search import check_objectives, search_field

#: The design parameters, in the order of a design vector (refine starts, rows).
PARAMS = ("alpha_deg", "beta_deg", "phi_x_deg", "phi_y_deg", "phi_z_deg", "bx_mm", "by_mm", "iso_min")
#: Row columns a [search] may optimise.
SEARCH_OBJECTIVES = ("cost", "zeta_cm", "area_cm2", "perimeter_cm", "iso_sum", "iso_mean", "iso_area_cm2",
                     "iso_min_actual") + PARAMS


class Span(StrictModel):
    """start, start + step, ... up to stop (inclusive when it lands on it)."""

    start: float
    stop: float
    step: float = Field(gt=0)

    @model_validator(mode="after")
    def _ordered(self):
        if self.stop < self.start:
            raise ValueError("stop must be >= start")
        if (self.stop - self.start) / self.step > 10_000:
            raise ValueError("more than 10,000 values")
        return self

    def values(self) -> list[float]:
        n = int(math.floor((self.stop - self.start) / self.step + 1e-9))
        return [round(self.start + i * self.step, 10) for i in range(n + 1)]


def _spec_form(value) -> str:
    """Which form a sweep parameter takes: a table {start, stop, step} or a list of values."""
    return "<span>" if isinstance(value, (dict, Span)) else "<list>"


#: A sweep parameter: a list of values, or a span {start, stop, step}. The discriminator picks the
#: form from the input, so an error is reported for that form only (not "Input should be a valid list").
ParamSpec = Annotated[Union[Annotated[list[float], Field(min_length=1, max_length=10_000), Tag("<list>")],
                            Annotated[Span, Tag("<span>")]], Discriminator(_spec_form),
                      BeforeValidator(lambda v: [v] if isinstance(v, (int, float)) and not isinstance(v, bool) else v)]
#: (a single number is the list of that value: sweep.iso_min=0.5, or sweep.iso_min=0.3,0.5,0.7 with --multirun)


def values(spec: ParamSpec) -> list[float]:
    return spec.values() if isinstance(spec, Span) else list(spec)


#: Allowed range of each sweep parameter (link angles also > 0).
PARAM_RANGES = {"alpha_deg": (0, 180), "beta_deg": (0, 180), "phi_x_deg": (-90, 90), "phi_y_deg": (-90, 90),
                "phi_z_deg": (-180, 180), "bx_mm": (0, 2000), "by_mm": (0, 2000), "iso_min": (0, 1)}


class Sweep(StrictModel):
    alpha_deg: ParamSpec = Span(start=5, stop=90, step=20)
    beta_deg: ParamSpec = Span(start=5, stop=90, step=20)
    phi_x_deg: ParamSpec = Span(start=-20, stop=20, step=10)
    phi_y_deg: ParamSpec = Span(start=-20, stop=20, step=10)
    phi_z_deg: ParamSpec = Span(start=-20, stop=20, step=10)
    bx_mm: ParamSpec = Span(start=50, stop=200, step=50)
    by_mm: ParamSpec = Span(start=50, stop=200, step=50)
    iso_min: ParamSpec = Span(start=0.1, stop=0.9, step=0.2)

    @field_validator(*PARAMS)
    @classmethod
    def _in_range(cls, spec, info):
        lo, hi = PARAM_RANGES[info.field_name]
        vs = values(spec)
        if not vs:
            raise ValueError("no values")
        if min(vs) < lo or max(vs) > hi or (info.field_name in ("alpha_deg", "beta_deg") and min(vs) <= 0):
            raise ValueError(f"values must lie in [{lo}, {hi}]" + (" and be > 0" if lo == 0 and info.field_name
                                                                    in ("alpha_deg", "beta_deg") else ""))
        return spec


class Geometry(StrictModel):
    """What the paper leaves to its Fig. 3 (docs/reproduction.md, Raven section)."""

    n_arms: Literal[1, 2, 4] = 4
    ports_mm: list[list[float]] | None = Field(None, description="[[x, y], ...] per arm; overrides bx/by")
    left_arms: list[bool] | None = Field(None, description="mirrored (left) arms; default 1 and 3")
    shoulder_tilt_deg: float = Field(90.0, ge=-90, le=90, description="axis 1 from vertical at phi = 0, outward")
    shoulder_tilt_toward: Literal["x", "y"] = Field(
        "x", description="outward along x (away from the other side) or y (away from the other pair)")
    mirror_left_phi: bool = Field(True, description="left arms turn by the mirror image of a right arm's rotation")
    mirror_plane: Literal["yz", "xz"] = Field("yz", description="the mirror: y-z plane (x -> -x: phi_y, phi_z "
                                                                  "negated) or x-z plane (phi_x, phi_z negated)")
    phi_order: Literal["zyx", "xyz"] = Field("zyx", description="R = Rz Ry Rx (zyx) or Rx Ry Rz (xyz) about the port")
    depth_mm: float = Field(raven_iv.REFERENCE_PLANE_DEPTH_MM, gt=0)
    step_mm: float = Field(2.0, gt=0.05, le=50)
    d4_max_mm: float = Field(raven_iv.D4_RANGE_MM[1], gt=0)
    theta2_range_deg: list[float] = Field(list(raven_iv.THETA2_RANGE_DEG), min_length=2, max_length=2)
    theta1_range_deg: list[float] | None = Field(
        list(raven_iv.THETA1_RANGE_RAVEN_II_DEG), min_length=2, max_length=2,
        description="shoulder range [lo, hi] about theta1_zero_toward (Table I lists none): the Raven II "
                    "hardware's, the range under which the paper's optimum ranks highest; [-180, 180] (or None "
                    "from Python): unlimited")
    theta1_zero_toward: Literal["x", "y", "-x", "-y"] = Field(
        "x", description="theta1 = 0: the elbow axis in the plane of the shoulder axis and this world direction "
                         "(as seen by arm 2; x negated for left arms), carried by the tilt and phi rotations: "
                         "'x' under horizontal shoulder axes is the downward vertical")

    @field_validator("theta1_range_deg")
    @classmethod
    def _theta1_range(cls, v):
        if v is not None and not (-360 <= v[0] < v[1] <= 360 and v[1] - v[0] <= 360):
            raise ValueError("[lo, hi] must satisfy -360 <= lo < hi <= 360 and hi - lo <= 360")
        return v

    @model_validator(mode="after")
    def _consistent(self):
        if self.d4_max_mm <= self.depth_mm:
            raise ValueError("d4_max_mm must exceed depth_mm or no point is reachable")
        lo, hi = self.theta2_range_deg
        if not 0 <= lo < hi <= 180:
            raise ValueError("theta2_range_deg must satisfy 0 <= lo < hi <= 180")
        for name in ("ports_mm", "left_arms"):
            v = getattr(self, name)
            if v is not None and len(v) != self.n_arms:
                raise ValueError(f"{name} must list {self.n_arms} arms")
        if self.ports_mm is not None and any(len(p) != 2 for p in self.ports_mm):
            raise ValueError("ports_mm entries are [x, y]")
        return self


class Refine(StrictModel):
    top_k: int = Field(5, ge=1, le=100)
    max_evals: int = Field(300, ge=10, le=100_000)

    @model_validator(mode="before")
    @classmethod
    def _no_starts(cls, data):
        """Starts are the refine plan's, taken from its parent run (manifests before plans held ``starts = null``)."""
        if isinstance(data, dict) and "starts" in data:
            if data["starts"] is not None:
                raise ValueError("starts: a refine starts from its parent run's best designs (run the grid with "
                                 "--refine); starts are no longer given in the config")
            data = {k: v for k, v in data.items() if k != "starts"}
        return data


class RavenSweepConfig(StrictModel):
    sweep: Sweep = Sweep()
    geometry: Geometry = Geometry()
    search: search_field("grid") = Field(
        "grid", description="'grid' (the sweep) or a [search] table (an optimiser); --refine follows a run with "
                            "a compass search from its best designs")
    refine: Refine = Refine()

    @model_validator(mode="after")
    def _search_objectives_are_columns(self):
        check_objectives(self.search, SEARCH_OBJECTIVES)
        return self

    @model_validator(mode="before")
    @classmethod
    def _refine_is_a_plan(cls, data):
        if isinstance(data, dict) and data.get("search") == "refine":
            raise ValueError("search = 'refine': a refine is a plan that follows a run: run the grid with --refine "
                             "(or surgopt.run(..., plan='refine'))")
        return data

    @model_validator(mode="after")
    def _ports_fix_bx_by(self):
        if self.geometry.ports_mm is not None:
            for name in ("bx_mm", "by_mm"):
                if len(values(getattr(self.sweep, name))) > 1:
                    raise ValueError(f"sweep.{name} has several values, but geometry.ports_mm fixes the ports "
                                     f"(bx_mm, by_mm are not used then): give one value")
        return self


Config = RavenSweepConfig
