"""port-place's rows' column vocabulary (issue 53: ``study.py`` was both the study's declaration and its columns): the
arms' column prefixes (``arms_of``: psm1, psm2, (psm3,) ecm), the design kernel's float columns as the rows store
them (named once, with unit and meaning, in ``kinematics/port/columns.py``), the cart's, the setup joints', the
docking's and a search's columns, each for a validated config or one as stored (a dict). Read by the study, the
design evaluator (``designs.py``), the layout of one row and the views.
"""
from __future__ import annotations

from surgopt.kinematics.port.columns import COLUMNS, PORT_SPACING
from surgopt.robots.dvrk.platforms import PLATFORMS
from surgopt.studies.port_place.arms import instruments_held
from surgopt.studies.port_place.carts import cart_of, has_cart
from surgopt.studies.port_place.config import PortPlaceConfig


def instruments_of(config=None) -> int:
    """The instrument arms of a config: validated, as stored (a dict), or none (2)."""
    if isinstance(config, dict):
        return int(config.get("robot", {}).get("instrument_count", 2))
    return 2 if config is None else config.robot.instrument_count


def arms_of(config=None) -> tuple[str, ...]:
    """The arms' column prefixes, instruments first, the camera last: psm1, psm2, (psm3,) ecm."""
    return tuple(f"psm{a + 1}" for a in range(instruments_of(config))) + ("ecm",)


#: The design kernel's float columns stored in the rows' first block, in the schema's order (named once, with unit
#: and meaning, in ``kinematics/port/columns.py``): the pair's and the camera's, then the third instrument's.
THIRD_COLUMNS = tuple(c.stored for c in COLUMNS[PORT_SPACING + 1:])
FLOAT_COLUMNS = tuple(c.stored for c in COLUMNS[:PORT_SPACING])


def float_columns(config=None) -> tuple[str, ...]:
    return FLOAT_COLUMNS + (THIRD_COLUMNS if instruments_of(config) == 3 else ())


#: The cart's columns (with ``cart.model`` other than "none"): the first pose of its grid at which every arm
#: docks (-1: none), that pose's origin on the floor and heading (the patient's floor frame).
CART_COLUMNS = ("cart_pose", "cart_x_mm", "cart_y_mm", "cart_heading_deg")


def cart_search_columns(config) -> tuple[str, ...]:
    """A search's cart dimensions (``cart.pose = "search"``; ``tables.searched_pose_box``), else none."""
    from surgopt.studies.port_place.tables import searched_pose_box

    if config is None or not has_cart(config):
        return ()
    cart = (config.get("cart") or {}) if isinstance(config, dict) else config.cart
    if (cart.get("pose") if isinstance(cart, dict) else cart.pose) != "search":
        return ()
    if isinstance(cart, dict):
        from surgopt.studies.port_place.config import Cart

        cart = Cart.model_validate(cart)
    return tuple(searched_pose_box(cart))


def suj_joint_columns(config) -> dict[str, tuple[tuple[str, str], ...]]:
    """Per arm (its column prefix), its setup joints' names in the cart's data and their row columns, in the
    order of the dVRK's ``simulated_position``: the column (prismatic, mm) first, then the revolute joints (deg)."""
    from surgopt.robots.dvrk.suj import INSTRUMENT_SUJS

    cart = PLATFORMS[cart_of(config)]
    out = {}
    for a, arm in enumerate(arms_of(config)):
        suj = cart.suj("ECM" if arm == "ecm" else INSTRUMENT_SUJS[a])
        out[arm] = tuple((row.name, f"{arm}_suj_{row.name}_{'mm' if row.prismatic else 'deg'}") for row in suj.links)
    return out


def roll_columns(config=None) -> tuple[str, ...]:
    """Each RCM instrument arm's docking roll at its port (none for serial arms, which keep the RCM in
    software and have no docking frame to turn: ``arms``)."""
    return tuple(f"{arm}_roll_deg" for arm in arms_of(config)[:-1]) if instruments_held(config).rolls else ()


def docking_columns(config=None) -> tuple[str, ...]:
    """Free docking (a search's dimensions): each instrument's base turned off the target's centre, yaw and
    pitch (0: the default docking); for a serial arm the yaw is its base's turn about the port, added to
    ``base_yaw_deg``, and the pitch stays 0."""
    return tuple(f"{arm}_docking_{angle}_deg" for arm in arms_of(config)[:-1] for angle in ("yaw", "pitch"))


def free_docking_columns(config=None) -> tuple[str, ...]:
    """The docking columns a search turns (``docking_columns``): yaw and pitch for an RCM arm, a serial arm's
    base yaw only (``arms``); the others stay 0."""
    angles = instruments_held(config).docking_angles
    return tuple(c for c in docking_columns(config) if c.rsplit("_", 2)[-2] in angles)


def aim_columns(config=None) -> tuple[str, ...]:
    """A surface search's dimensions (``search_ports = "surface"``): each port's top-view point, x and y (mm)."""
    ports = (config.get("search_ports", "sites") if isinstance(config, dict)
             else "sites" if config is None else config.search_ports)
    return tuple(f"{arm}_aim_{c}_mm" for arm in arms_of(config) for c in "xy") if ports == "surface" else ()


SERIAL_ROLES = ("instrument", "camera")


def stance_columns(config=None) -> tuple[str, ...]:
    """A search's serial-arm stances: for each serial arm (the instruments' one, the camera's) whose
    ``stance_range_m`` > 0, its RCM moved out from its base and up, off ``rcm_in_base_m`` (m)."""
    robot = (config.get("robot", {}) if isinstance(config, dict)
             else {} if config is None else config.robot.model_dump())
    return tuple(f"{role}_stance_{d}_m" for role in SERIAL_ROLES
                 if (robot.get(f"{role}_serial") or {}).get("stance_range_m", 0.0) > 0 for d in ("out", "up"))


#: (#54 item 3) Each layout's least clearance between its arms over every target point (mm; measured for the
#: layouts feasible on the link tables' sampled points, NaN elsewhere): ``designs.decided_over_the_whole_target``.
WHOLE_TARGET_COLUMN = "links_whole_target_mm"


#: A searched docking roll's range (deg): each PSM's frame turned about its neutral shaft, x toward y.
ROLL_RANGE_DEG = (-90.0, 90.0)


def searched_roll_columns(cfg: PortPlaceConfig) -> tuple[str, ...]:
    """Each PSM's docking roll as a search's dimension (``robot.docking_roll = 'search'``): the rows' own roll
    columns, whose value is the trial's."""
    return roll_columns(cfg) if cfg.robot.docking_roll == "search" else ()


#: The two-instrument study's docking and site columns.
DOCKING_COLUMNS = docking_columns()


SITE_COLUMNS = tuple(f"{arm}_site" for arm in arms_of())


def links_of(config) -> bool:
    """Whether the arms' links decide feasible (``tables.links_decide``) in a config, validated or as stored."""
    if not has_cart(config):
        return False
    if isinstance(config, dict):
        # as stored: the field's value; absent, its default (0: on); None, a run from before it was the default
        least = (config.get("constraints") or {}).get("min_link_clearance_mm", 0.0)
        return least is not None and least != "off"
    from surgopt.studies.port_place.tables import links_decide

    return links_decide(config)
