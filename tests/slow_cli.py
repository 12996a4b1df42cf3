"""The surgopt CLI with one phase slowed by a compiled kernel that cannot be interrupted, for the stop tests
(tests/test_faults.py) and docs/interrupt_trials.py.

    python tests/slow_cli.py SECONDS PHASE surgopt-arguments...

PHASE ``chunk``: the third chunk (index 2) also spins SECONDS in a ``nogil`` numba loop (in its worker
thread, or in the main thread with ``--jobs 1``), as a long chunk of a real kernel does; ``warm``: the study's
warm-up (where a first run compiles, in LLVM, without returning to Python) spins SECONDS first. ``spinning`` is
written to stderr when the slow phase starts. The loop's length is calibrated on this machine, so it lasts
about SECONDS whatever the CPU.
"""
from __future__ import annotations

import dataclasses
import math
import sys
import time


def main() -> None:
    from surgopt import interrupts

    interrupts.install()
    seconds, phase, args = float(sys.argv[1]), sys.argv[2], sys.argv[3:]
    spin = _spinner(seconds)

    import surgopt.plans as plans

    if phase == "chunk":
        run_task = plans.run_task

        def slow_task(study, cfg, chunk, task):
            rows = run_task(study, cfg, chunk, task)
            if task.index == 2:
                spin()
            return rows

        plans.run_task = slow_task
    elif phase == "warm":
        import surgopt.runner as runner

        warm = runner._warm_up

        def slow_warm_up(study, cfg, say=None):
            def warm_up(c):
                spin()
                study.warm_up(c)

            warm(dataclasses.replace(study, warm_up=warm_up), cfg, say)

        runner._warm_up = slow_warm_up
    else:
        raise SystemExit(f"unknown phase {phase!r}")
    sys.argv = ["surgopt", *args]
    from surgopt.cli import run

    run()


def _spinner(seconds: float):
    from numba import njit

    @njit(nogil=True, cache=False)
    def loop(n):  # pragma: no cover - compiled
        x = 0.0
        for i in range(n):
            x = math.sin(x + i)
        return x

    loop(10)
    n = 200_000
    while True:
        t0 = time.perf_counter()
        loop(n)
        dt = time.perf_counter() - t0
        if dt > 0.05:
            break
        n *= 4
    total = int(n * seconds / dt)

    def spin():
        sys.stderr.write("spinning\n")
        sys.stderr.flush()
        loop(total)

    return spin


if __name__ == "__main__":
    main()
