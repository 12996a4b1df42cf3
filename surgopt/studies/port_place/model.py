"""port-place's prepared model: everything a config implies, built once (``prepare``) and passed explicitly to
the kernels' drivers, the rows, the layout of one row and the views (issue 53).

The model follows Pinocchio's Model/Data split and STUMPY's "prepare once in the driver": ``PortModel`` holds the
config's geometry (the candidate sites, the target's points and centre, each port's default docking frame), the
kernels' named tuples (the instrument arm's ``ArmLimits``, its ``Approach`` cone, the ``Camera``, the
``Criteria``), how the arms hold their tools (``arms.py``), and, built on first use, the per-port and per-pair
tables of the default docking (``grid``: ``tables.PortTables``, reach and isotropy per site and point) and the
cart's dock tables (``dock``), which the grid's chunks combine into designs. A search's tasks build only the tables
of the ports they evaluate (``tables.port_tables``), so a worker that searches never builds the grid's.

``model_of(cfg)`` is the entries' one way to a model (a task, a design evaluated alone, a view of a stored run): it
keeps the one model of the config a process is running, so the tasks of a run on threads share the parent's and a
worker process builds its own on its first task (rebuilding is cheaper than pickling the tables to every worker,
and gives the same arrays). Below an entry the model is an argument.
"""
from __future__ import annotations

import dataclasses
import threading
from functools import cached_property
from typing import NamedTuple

import numpy as np

from surgopt.studies.port_place.arms import RcmCamera, RcmInstruments, camera_held, instruments_held
from surgopt.studies.port_place.carts import LATERAL
from surgopt.studies.port_place.config import PortPlaceConfig, instrument_of
from surgopt.studies.port_place.geometry import sites_mm, target_points_mm
from surgopt.studies.port_place.tables import (DockTables, approach, camera_of, criteria, dock_tables,
                                               instrument_frames, port_tables, third_frames)


class GridTables(NamedTuple):
    """The default docking's tables: ``PortTables`` (what ``design_columns`` combines), reach[site, point] and
    isotropy[site, point]."""

    tables: object
    reach: np.ndarray
    dexterity: np.ndarray


@dataclasses.dataclass(frozen=True, eq=False)
class PortModel:
    """A config's prepared model (``prepare``). Every array is in metres; ``cfg`` is the validated config it was
    built from (a search's stance moves swap it, ``with_config``)."""

    cfg: PortPlaceConfig
    sites_m: np.ndarray  # (n, 3) candidate port sites
    targets_m: np.ndarray  # (m, 3) the target's points
    centre_m: np.ndarray  # (3,) the target's centre
    rot: np.ndarray  # (n, 3, 3) each site's default docking frame (its z: the shaft toward the centre)
    criteria: object  # kinematics.port.place.Criteria
    camera: object  # kinematics.port.place.Camera
    limits: object  # the instrument arm's kinematics.port.place.ArmLimits
    cone: object  # kinematics.port.place.Approach of the target for the instrument's wrist
    instruments: RcmInstruments  # how the instruments are held (``arms``): an RCM arm, or a serial arm's kernel
    endoscope: RcmCamera  # how the endoscope is held (``arms``)

    @cached_property
    def grid(self) -> GridTables:
        """The per-port and per-pair tables at the default docking (built on first use: a search never needs
        them), with the cart's docking (``dock``)."""
        return GridTables(*port_tables(self, self.sites_m, self.rot, dock=self.dock))

    @cached_property
    def site_reach(self) -> tuple[np.ndarray, np.ndarray]:
        """(reach, isotropy) of the instruments at every candidate site and target point, docked as the grid docks
        them: what the page colours the target by, without the pair, cart and link tables ``grid`` builds (the
        default run's page spent 6.5 s of 13.6 on link tables it never read; issue 56's report <= 10 s)."""
        if "grid" in self.__dict__:
            return self.grid[1], self.grid[2]
        frames = instrument_frames(self, self.sites_m, self.rot)
        reach, dex, _, _ = self.instruments.reach(self, self.sites_m, frames, None)
        return reach, dex

    @cached_property
    def instrument_rot(self) -> np.ndarray:
        """(n, 3, 3) Each site's instrument docking frame: the default frame turned about its shaft by the
        config's docking roll (``instrument_frames``)."""
        return instrument_frames(self, self.sites_m, self.rot)

    @cached_property
    def third_rot(self) -> np.ndarray | None:
        """(n, 3, 3) The third instrument's docking frames where they are its own (the Si PSM3, ``third_frames``),
        else None (the first two's, ``instrument_rot``)."""
        return third_frames(self, self.sites_m)

    @cached_property
    def third_site_reach(self) -> tuple[np.ndarray, np.ndarray] | None:
        """(reach, isotropy) of the third instrument at every candidate site and target point where it docks in
        frames of its own (the Si PSM3, ``third_rot``), else None: what the page colours its target by."""
        from surgopt.studies.port_place.arms import instrument_reach

        if self.third_rot is None:
            return None
        return instrument_reach(self, self.sites_m, self.third_rot)

    @cached_property
    def organ_crossing(self) -> np.ndarray | None:
        """[site, point] The organ the shaft from each candidate site to each target point crosses (an index of
        ``organs.organ_grids``, -1 none; ``organs.shafts_crossing``), once: the reach tables' mask and the closing
        report's counts; None without organs."""
        from surgopt.studies.port_place.organs import organ_grids, shafts_crossing

        grids = organ_grids(self.cfg.patient)
        return shafts_crossing(self.sites_m, self.targets_m, grids) if grids else None

    @property
    def shafts_clear_at_sites(self) -> np.ndarray | None:
        """[site, point] Whether that shaft crosses no organ (``organ_crossing``); None without organs."""
        return None if self.organ_crossing is None else self.organ_crossing < 0

    @cached_property
    def whole_target(self) -> tuple[np.ndarray, np.ndarray]:
        """Every target point in groups of neighbours, and the groups' offsets (``clashes.whole_target_points``):
        what each layout's links are measured over (#54 item 3), ordered once."""
        from surgopt.studies.port_place.clashes import whole_target_points

        return whole_target_points(self)

    @cached_property
    def dock(self) -> "DockTables":
        """Which of the cart's setup joints dock which arm at which site and cart pose (``dock_tables``)."""
        return dock_tables(self)

    def with_config(self, cfg: PortPlaceConfig) -> "PortModel":
        """The same model read through ``cfg`` (a serial arm's RCM moved by a search's stance; nothing the model
        precomputed depends on it)."""
        return dataclasses.replace(self, cfg=cfg)


def prepare(cfg: PortPlaceConfig) -> PortModel:
    """Build the model of a validated config (the grid's tables on first use of ``PortModel.grid``)."""
    from surgopt.kinematics.port import place as K

    if cfg.robot.docking_rolls_deg:  # a caller's slip, not a user's: each roll's block has a model of its own
        raise RuntimeError("a port-place model is of one docking roll: ask for rolls.at_docking(cfg, docking)'s, or a "
                           "row's (rolls.model_for)")
    sites = sites_mm(cfg) / 1000
    centre = np.asarray(cfg.target.centre_mm, float) / 1000
    instruments, endoscope = instruments_held(cfg).prepare(cfg, centre), camera_held(cfg).prepare(cfg)
    return PortModel(
        cfg=cfg, sites_m=sites, targets_m=target_points_mm(cfg.target) / 1000, centre_m=centre,
        rot=K.docking_frames(sites, centre, LATERAL), criteria=criteria(cfg), camera=camera_of(cfg),
        limits=instruments.limits(cfg), cone=approach(cfg.target, instrument_of(cfg).wrist_bend_rad),
        instruments=instruments, endoscope=endoscope)


#: The models a process keeps, the latest last: two, so that the threads working across a boundary between two
#: docking rolls' blocks (``rolls.py``) do not rebuild each other's.
HELD_MODELS = 2
_held: dict = {}  # the canonical JSON of a config -> its model
_held_lock = threading.Lock()


def model_of(cfg: PortPlaceConfig) -> PortModel:
    """The model of ``cfg``, built once per process and kept while the process runs that config (the
    HELD_MODELS latest configs: another replaces the oldest)."""
    key = cfg.model_dump_json()
    with _held_lock:
        if key not in _held:
            while len(_held) >= HELD_MODELS:
                _held.pop(next(iter(_held)))
            _held[key] = prepare(cfg)
        else:
            _held[key] = _held.pop(key)  # the latest last
        return _held[key]
