"""The one registry of patient carts (platforms) port-place docks its arms with: ``PLATFORMS``.

A platform is data: its name in configs (``cart.model``) and in words, the shipped arms it carries for each role
(``robots/models.py``'s names), each arm's setup joints (``dvrk.suj``), where its world frame stands above the
floor, its arms' own links as skeletons and capsules (``dvrk.links``), and which family of setup joints it has
(``suj_family``: how an arm is docked by them, the one thing port-place's cart classes dispatch on). Every other
list of carts (the config's choices, the names in words, the carts whose links are modelled) is derived from it,
and an arm's role is spelled one way: ``ROLES``.

Adding a platform: a ``Platform`` here (its arms registered in ``robots/models.py``); a new family of setup joints
also needs its cart class in ``studies/port_place/carts.py``.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Mapping

from surgopt.robots.dvrk import links as L
from surgopt.robots.dvrk import suj as S

#: An arm's role on a cart, spelled one way everywhere: the instruments (the working pair, then the third) and
#: the camera arm. The rows' column prefixes are these in lower case (``column_prefix``).
INSTRUMENT_ROLES = S.INSTRUMENT_SUJS
CAMERA_ROLE = "ECM"
ROLES = (*INSTRUMENT_ROLES, CAMERA_ROLE)


def column_prefix(role: str) -> str:
    """The rows' prefix of a role's columns: "PSM1" -> "psm1"."""
    return role.lower()


def role_of(prefix: str) -> str:
    """The role of a rows' column prefix: "psm1" -> "PSM1" (the inverse of ``column_prefix``)."""
    role = prefix.upper()
    if role not in ROLES:
        raise KeyError(f"{prefix!r} names no arm role ({', '.join(map(column_prefix, ROLES))})")
    return role


@dataclass(frozen=True)
class ArmLinks:
    """A cart's arms' own links beyond their setup joints: the PSM's and the ECM's skeletons and capsules."""

    psm_frames: tuple
    psm_capsules: tuple
    ecm_frames: tuple
    ecm_capsules: tuple

    def of(self, role: str) -> tuple:
        """(skeleton, capsules) of the arm in ``role``."""
        return (self.ecm_frames, self.ecm_capsules) if role == CAMERA_ROLE else (self.psm_frames, self.psm_capsules)


@dataclass(frozen=True)
class Platform:
    """One patient cart and the arms it carries.

    ``suj_family``: "classic" (a prismatic column and five revolute joints: the docking frame's roll about the
    shaft is free, S2) or "si" (a column, planar joints and two fixed links: one orientation per yaw, psi*, S3-S7).
    ``world_above_floor_m`` and its source: the files give no floor (``dvrk.suj``). ``footprint_m``: the cart's base
    on the floor, ((x_lo, y_lo), (x_hi, y_hi)) m in its world frame (+y toward the patient when it faces the
    target), with its source: what must stand clear of the table (``cart.clear_of_table_mm``)."""

    name: str
    title: str
    instrument_arm: str
    camera_arm: str
    sujs: Mapping[str, S.Suj]
    world_above_floor_m: float
    world_above_floor_source: str
    links: ArmLinks
    suj_family: str
    footprint_m: tuple
    footprint_source: str
    #: The dVRK console's arm files for a simulated system (sawIntuitiveResearchKit share/arm/: PSM, ECM); a real
    #: system names its own calibrated files in their place.
    console_arm_files: tuple = ()

    def suj(self, role: str) -> S.Suj:
        """The setup joints of the arm in ``role`` ("PSM1" ... "ECM")."""
        return self.sujs[role]

    def own_links(self, role: str) -> tuple:
        """(skeleton, capsules) of the arm's own links in ``role``."""
        return self.links.of(role)

    @property
    def roll_is_free(self) -> bool:
        """Whether the setup joints leave the docking frame's roll about the shaft to choose (the Classic's)."""
        return self.suj_family == "classic"


#: The Classic patient cart's base on the floor (m, its world frame): the extent of its own mesh's vertices
#: (tools/cart_footprint.py). Its column above the 0.37 m base lies within it (x +-0.095, y -0.528..0.004).
CLASSIC_FOOTPRINT_M = ((-0.456, -0.568), (0.456, 0.365))
CLASSIC_FOOTPRINT_SOURCE = ("shashank3199/dvrk_urdf f4e68a8c, suj_description/meshes/Classic/base_link.stl (sha256 "
                            "15cce974b843...), placed by patient_cart.classic.urdf.xacro; its x, y are the dVRK cart "
                            "world's (the setup joints' mounts agree)")

PLATFORMS: dict[str, Platform] = {
    "classic": Platform(
        "classic", "Classic", "dvrk_psm_classic", "dvrk_ecm_classic", S.CLASSIC, 0.0,
        "taken on the floor: the files' sample dockings put the RCMs 0.91-0.99 m above it, a port on an abdomen "
        "over a 0.8 m table",
        ArmLinks(L.PSM_CLASSIC_FRAMES, L.PSM_CLASSIC_CAPSULES, L.ECM_CLASSIC_FRAMES, L.ECM_CLASSIC_CAPSULES),
        "classic", CLASSIC_FOOTPRINT_M, CLASSIC_FOOTPRINT_SOURCE,
        ("arm/PSM_KIN_SIMULATED_LARGE_NEEDLE_DRIVER_400006.json", "arm/ECM_KIN_SIMULATED_STRAIGHT.json")),
    "si": Platform(
        "si", "Si", "dvrk_psm_si", "dvrk_ecm_si", S.SI, 0.53,
        "chosen: the Si's samples put the RCMs 0.39-0.45 m above its world frame; 0.53 m puts its four sample RCMs "
        "at the Classic's samples' mean height (an assumption, not a measurement of the Si cart)",
        # the Si's ECM beyond its setup joints is the Classic's line behind the RCM (its DH yaw, pitch and
        # insertion offset are the same; an assumption, the Si ECM's own description not transcribed)
        ArmLinks(L.PSM_SI_FRAMES, L.PSM_SI_CAPSULES, L.ECM_CLASSIC_FRAMES, L.ECM_CLASSIC_CAPSULES),
        "si", CLASSIC_FOOTPRINT_M, "assumed: the Classic's (" + CLASSIC_FOOTPRINT_SOURCE + "); the Si's base mesh is "
        "not in that repository, only its tower (Si/tower.stl, 0.27 m square)",
        ("arm/PSM_Si_KIN_SIMULATED_LARGE_NEEDLE_DRIVER_420006.json", "arm/ECM_Si_KIN_SIMULATED_STRAIGHT.json")),
}

#: The platform ``cart.model = "auto"`` resolves to where the config's arms are its own.
AUTO_PLATFORM = "classic"
def cart_models() -> tuple[str, ...]:
    """``cart.model``'s values: no cart (docking assumed), each platform of ``PLATFORMS``, or "auto"."""
    return ("none", *PLATFORMS, "auto")


#: ``cart_models()`` of the shipped platforms (the config's schema).
CART_MODELS = cart_models()


def platform_of(model: str) -> Platform | None:
    """The platform a ``cart.model`` names, or None for "none"."""
    return None if model == "none" else PLATFORMS[model]
