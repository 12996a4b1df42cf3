"""The docking roll as a dimension of the enumeration (#54 item 2): ``robot.docking_rolls_deg`` lists the rolls
each layout is docked at, each PSM's frame turned about its neutral shaft by the roll, mirrored by its port's side
(``robot.docking_roll_deg``'s rule); with ``docking_rolls_per_side`` every pair of them, one for the ports on the
patient's left and one for those on the right (``docking_roll_right_deg``), so that two PSMs on either side of the
midline take rolls of their own. Every row is docked as it is scored and the answer is the cheapest feasible row
over every docking: no screen after the rows decides it.

The enumeration is one block of designs per docking (a (left, right) pair of rolls), in the list's order (per
side: the left's roll major): design d of block b is design ``b * per_roll + d`` (``per_roll``: the designs of one
docking), so a design's number says its docking, and a row's ``psm1_roll_deg`` ... the signed roll each PSM took.
A block is the enumeration of the config at that docking alone (``at_docking``): its model (the port, dock and
link tables) is that config's, and a view of a stored row reads the model of its row's docking (``model_for``). One
docking (the list unset) is the config's own ``docking_roll_deg`` and ``docking_roll_right_deg``.
"""
from __future__ import annotations

from surgopt.studies.port_place.config import PortPlaceConfig


def n_designs(n_sites: int, instruments: int = 2) -> int:
    """Designs of ``n_sites`` candidates (``designs.design_columns``'s enumeration): an unordered working
    pair of instruments, then (three instruments) the third's port, then the camera's, all distinct:
    C(n, 2) (n - 2), times (n - 3) with a third instrument."""
    d = n_sites * (n_sites - 1) // 2 * max(0, n_sites - 2)
    return d * max(0, n_sites - 3) if instruments == 3 else d


def dockings(cfg: PortPlaceConfig) -> tuple[tuple[float, float], ...]:
    """The (left, right) rolls (deg) of each block of the enumeration: the list's rolls on both sides, or every
    pair of them per side, or the config's one docking."""
    r = cfg.robot
    if not r.docking_rolls_deg:
        return ((r.docking_roll_deg, r.docking_roll_deg if r.docking_roll_right_deg is None
                 else r.docking_roll_right_deg),)
    if r.docking_rolls_per_side:
        return tuple((left, right) for left in r.docking_rolls_deg for right in r.docking_rolls_deg)
    return tuple((roll, roll) for roll in r.docking_rolls_deg)


def at_docking(cfg: PortPlaceConfig, docking: tuple[float, float]) -> PortPlaceConfig:
    """The config of one block: ``cfg`` docked at ``docking`` ((left, right) rolls, deg) alone."""
    if not cfg.robot.docking_rolls_deg:
        return cfg
    left, right = (float(v) for v in docking)
    return cfg.model_copy(update={"robot": cfg.robot.model_copy(update={
        "docking_roll_deg": left, "docking_roll_right_deg": None if right == left else right,
        "docking_rolls_deg": None, "docking_rolls_per_side": False})})


def first_docking(cfg: PortPlaceConfig) -> PortPlaceConfig:
    """The first block's config: what a view of the whole run shows where it needs one docking's tables (the
    sites' reach), what the warm-up builds first."""
    return at_docking(cfg, dockings(cfg)[0])


def per_roll(cfg: PortPlaceConfig) -> int:
    """The designs of one docking's block (``n_designs`` of the candidate sites)."""
    from surgopt.studies.port_place.geometry import sites_mm

    return n_designs(len(sites_mm(cfg)), cfg.robot.instrument_count)


def blocks(cfg: PortPlaceConfig, start: int, stop: int) -> list[tuple[PortPlaceConfig, int, int, int]]:
    """Designs ``start`` .. ``stop`` - 1 of the enumeration (``stop`` clamped to its end) as (the block's config,
    its first and past-last local design, the block's offset), one entry per block they span."""
    docks, per = dockings(cfg), per_roll(cfg)
    stop = min(stop, per * len(docks))
    out = []
    for b in range(start // per, (max(stop, start + 1) - 1) // per + 1):
        lo, hi = max(start, b * per), min(stop, (b + 1) * per)
        if lo < hi:
            out.append((at_docking(cfg, docks[b]), lo - b * per, hi - b * per, b * per))
    return out


def config_of_row(cfg: PortPlaceConfig, row: dict) -> PortPlaceConfig:
    """The config a stored row was docked by: its block's (by its design number), or for a row of its own (a given
    layout's, design -1) the rolls its PSMs took (``psm1_roll_deg`` ..., unsigned by their ports' sides; a side no
    PSM takes keeps the other's)."""
    docks = dockings(cfg)
    if len(docks) == 1:
        return cfg
    design = row.get("design_id")
    if design is not None and design >= 0:
        return at_docking(cfg, docks[min(int(design) // per_roll(cfg), len(docks) - 1)])
    sides = {}
    for arm in ("psm1", "psm2", "psm3"):
        if f"{arm}_roll_deg" in row:
            left = row.get(f"{arm}_x_mm", 0.0) >= 0
            sides.setdefault("left" if left else "right", row[f"{arm}_roll_deg"] * (1.0 if left else -1.0))
    left = sides.get("left", sides.get("right", 0.0))
    return at_docking(cfg, (left, sides.get("right", left)))


def model_for(cfg: PortPlaceConfig, row: dict):
    """The model a stored row was computed on (``model.model_of`` of ``config_of_row``)."""
    from surgopt.studies.port_place.model import model_of

    return model_of(config_of_row(cfg, row))


def docking_words(cfg: PortPlaceConfig, row: dict) -> str:
    """The answer's docking among those the rows enumerated, each PSM's turn (the Classic's roll, the Si's yaw off
    psi*) signed by its port's side."""
    r = config_of_row(cfg, row).robot
    right = r.docking_roll_deg if r.docking_roll_right_deg is None else r.docking_roll_right_deg
    signed = ", ".join(f"{a.upper()} {row[f'{a}_roll_deg']:+.0f}" for a in ("psm1", "psm2", "psm3")
                       if f"{a}_roll_deg" in row)
    which = (f"{r.docking_roll_deg:g} deg" if right == r.docking_roll_deg else
             f"{r.docking_roll_deg:g} deg on the patient's left, {right:g} on the right")
    enumerated = ", ".join(f"{x:g}" for x in cfg.robot.docking_rolls_deg)
    return (f"{which} ({signed} by their ports' sides), the cheapest feasible row over the dockings the rows "
            f"enumerated: {enumerated} deg" + (" on each side, every pair (robot.docking_rolls_per_side)"
                                               if cfg.robot.docking_rolls_per_side else " (robot.docking_rolls_deg)"))
