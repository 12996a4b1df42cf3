"""port-place's rows' column vocabulary (issue 53: ``study.py`` was both the study's declaration and its columns): the
arms' column prefixes (``arms_of``: psm1, psm2, (psm3,) ecm) and the design kernel's float columns as the rows store
them (named once, with unit and meaning, in ``kinematics/port/columns.py``). Read by the study, the layout of one
row and the views; it imports no other port-place module.
"""
from __future__ import annotations

from surgopt.kinematics.port.columns import COLUMNS, PORT_SPACING


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
