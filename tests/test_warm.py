"""The warm-up compiles what a run's chunks call, so that a run compiles only in its announced warm-up (where a
stop, a notice and the cache's lock apply) and never inside a chunk, where the progress bar would stand still
for minutes (issue 38: ``metric=standard`` compiled its SIMD-lane walk in the first chunks, 26 s).

Each case runs in a fresh process: the warm-up must add compiled functions (loaded from the cache or compiled:
the premise), and the first chunk of the study's own plan must add none."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest


PROBE = """
import json, sys
import surgopt.kinematics  # numba configured first
from numba.core.dispatcher import Dispatcher
from surgopt.compose import variants
from surgopt.plans import Task, run_task
from surgopt.studies import get_study

added = []
real = Dispatcher.add_overload
def add_overload(self, cres):
    added.append(self.py_func.__qualname__)
    return real(self, cres)
Dispatcher.add_overload = add_overload

study = get_study(sys.argv[1])
(v,) = variants(study, None, sys.argv[2:])
cfg = v.config
study.warm_up(cfg)
warm = list(added)
added.clear()
chunk = min(study.auto_chunk(cfg), 64)
run_task(study, cfg, chunk, Task(0))
print(json.dumps({"warm": len(warm), "chunk": sorted(set(added))}))
"""

CASES = [
    ("rcm-grid",),
    ("rcm-grid", "metric=standard"),
    ("rcm-grid", "robot.model=ur5e"),
    ("rcm-track",),
    ("raven-sweep",),
    ("suture-sim",),
    ("port-place",),
    ("port-place", 'robot.instrument_serial={model = "pa10_7c", rcm_in_base_m = [0.65, 0.0, 0.5]}',
     "constraints.min_external_clearance_mm=150.0"),
]


@pytest.mark.parametrize("case", CASES, ids=[" ".join(c)[:40] for c in CASES])
def test_the_warm_up_compiles_every_kernel_the_first_chunk_calls(case):
    r = subprocess.run([sys.executable, "-c", PROBE, *case], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    got = json.loads(r.stdout.strip().splitlines()[-1])
    assert got["warm"] > 0  # the premise: the warm-up itself loaded or compiled the kernels
    assert got["chunk"] == [], f"compiled in a chunk, not in the warm-up: {got['chunk']}"


def test_every_warm_variant_is_a_case_here():
    """``surgopt warm`` compiles a study's default and its ``warm_variants``: each is checked above."""
    from surgopt.studies import STUDIES, get_study

    declared = {(name, *v) for name in STUDIES for v in ((), *get_study(name).warm_variants)}
    assert declared <= set(CASES), declared - set(CASES)
