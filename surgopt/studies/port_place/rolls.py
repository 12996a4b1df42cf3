"""The docking roll as a dimension of the enumeration (#54 item 2): ``robot.docking_rolls_deg`` lists the rolls
each layout is docked at, each PSM's frame turned about its neutral shaft by the roll, mirrored by its port's side
(``robot.docking_roll_deg``'s rule), so that every row is docked as it is scored and the answer is the cheapest
feasible row over every roll: no screen after the rows decides it.

The enumeration is one block of designs per roll, in the list's order: design d of the block at roll b is design
``b * per_roll + d`` (``per_roll``: the designs of one roll), so a design's number says its roll, and a row's
``psm1_roll_deg`` ... the signed roll each PSM took. A block is the enumeration of the config at that single roll
(``at_roll``): its model (the port, dock and link tables) is that config's, and a view of a stored row reads the
model of its row's roll (``model_for``). One roll (the list unset) is the config's own ``docking_roll_deg``.
"""
from __future__ import annotations

from surgopt.studies.port_place.config import PortPlaceConfig


def docking_rolls(cfg: PortPlaceConfig) -> tuple[float, ...]:
    """The rolls the enumeration docks each layout at (deg): the list, or the config's one roll."""
    rolls = cfg.robot.docking_rolls_deg
    return tuple(rolls) if rolls else (cfg.robot.docking_roll_deg,)


def at_roll(cfg: PortPlaceConfig, roll_deg: float) -> PortPlaceConfig:
    """The config of one block: ``cfg`` docked at ``roll_deg`` alone (the list unset)."""
    if not cfg.robot.docking_rolls_deg:
        return cfg
    return cfg.model_copy(update={"robot": cfg.robot.model_copy(update={"docking_roll_deg": float(roll_deg),
                                                                         "docking_rolls_deg": None})})


def n_designs(n_sites: int, instruments: int = 2) -> int:
    """Designs of ``n_sites`` candidates (``designs.design_columns``'s enumeration): an unordered working
    pair of instruments, then (three instruments) the third's port, then the camera's, all distinct:
    C(n, 2) (n - 2), times (n - 3) with a third instrument."""
    d = n_sites * (n_sites - 1) // 2 * max(0, n_sites - 2)
    return d * max(0, n_sites - 3) if instruments == 3 else d


def per_roll(cfg: PortPlaceConfig) -> int:
    """The designs of one roll's block (``n_designs`` of the candidate sites)."""
    from surgopt.studies.port_place.geometry import sites_mm

    return n_designs(len(sites_mm(cfg)), cfg.robot.instrument_count)


def blocks(cfg: PortPlaceConfig, start: int, stop: int) -> list[tuple[PortPlaceConfig, int, int, int]]:
    """Designs ``start`` .. ``stop`` - 1 of the enumeration as (the block's config, its first and past-last local
    design, the block's offset), one entry per roll block they span."""
    rolls, per = docking_rolls(cfg), per_roll(cfg)
    if len(rolls) == 1:
        return [(cfg, start, stop, 0)]
    out = []
    for b in range(start // per, (max(stop, start + 1) - 1) // per + 1):
        lo, hi = max(start, b * per), min(stop, (b + 1) * per)
        if lo < hi:
            out.append((at_roll(cfg, rolls[b]), lo - b * per, hi - b * per, b * per))
    return out


def config_of_design(cfg: PortPlaceConfig, design_id: int) -> PortPlaceConfig:
    """The config of the block a design of the enumeration lies in (a given layout's, -1, and a search's trials
    carry their roll in their own config: ``cfg`` itself)."""
    rolls = docking_rolls(cfg)
    if len(rolls) == 1 or design_id is None or design_id < 0:
        return cfg
    return at_roll(cfg, rolls[min(int(design_id) // per_roll(cfg), len(rolls) - 1)])


def config_of_row(cfg: PortPlaceConfig, row: dict) -> PortPlaceConfig:
    """The config a stored row was docked by: its roll block's (``config_of_design``), or for a row of its own (a
    given layout's) the roll its PSMs took (``psm1_roll_deg``, unsigned by its port's side)."""
    if len(docking_rolls(cfg)) == 1:
        return cfg
    design = row.get("design_id")
    if design is not None and design >= 0:
        return config_of_design(cfg, design)
    x = row.get("psm1_x_mm", 0.0)
    return at_roll(cfg, row["psm1_roll_deg"] * (1.0 if x >= 0 else -1.0))


def model_for(cfg: PortPlaceConfig, row: dict):
    """The model a stored row was computed on (``model.model_of`` of ``config_of_row``)."""
    from surgopt.studies.port_place.model import model_of

    return model_of(config_of_row(cfg, row))
