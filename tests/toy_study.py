"""A study that is not surgopt's: proves the protocol (tests/test_studies.py). Rows: x and x^2."""
from __future__ import annotations

import math

import numpy as np
from pydantic import Field

from surgopt.config import StrictModel
from surgopt.studies import Flag, Study, Summary


class ToyConfig(StrictModel):
    n: int = Field(10, ge=1, le=1000)
    offset: float = 0.0


def schema():
    import pyarrow as pa

    return pa.schema([pa.field("i", pa.int64()), pa.field("x", pa.float64()), pa.field("square", pa.float64())])


def compute_task(cfg, chunk, index):
    i = np.arange(index * chunk, min(cfg.n, (index + 1) * chunk))
    x = i + cfg.offset
    return {"i": i, "x": x.astype(float), "square": (x * x).astype(float)}


def summary(parts):
    s = parts.column("square")
    return Summary({"rows": parts.num_rows, "best_square": float(s.max())},
                   {"positive": int((s > 0).sum()), "zero": int((s == 0).sum())})


STUDY = Study(
    name="toy", kernel_version="toy-1", config_model=ToyConfig, default_config="none.toml", help="A toy.",
    config_help="TOML", schema=schema, key_columns=("i",), objective="square", auto_chunk=lambda cfg: 3,
    n_tasks=lambda cfg, chunk: math.ceil(cfg.n / chunk), warm_up=lambda cfg: None, compute_task=compute_task,
    summary=summary, feasible_mask=lambda t: t["square"].to_numpy() > 0, figures=lambda *a: [],
    flags=(Flag("--shift", "offset by one", config_update={"offset": 1.0}),))
