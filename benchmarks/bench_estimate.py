"""How well each study's estimate (what --dry-run prints and the budget holds a config to) predicts this
machine: the estimate's single-core seconds against the CPU time of the same tasks in this process.

Run:  python benchmarks/bench_estimate.py
The cost constants (ns per pose, per node, per step) were measured on one AVX-512 machine; on another CPU
or under load the ratio moves, which is why this is a benchmark and not a test (tests/test_studies.py
holds what does not depend on the machine: the row count and the scaling). A ratio far from 1 on your
machine means the budget refuses too early (ratio > 1) or too late (< 1).
"""
from __future__ import annotations

import time

from surgopt.studies import get_study

CASES = [
    ("rcm-grid", {"candidates": {"grid": {"x_count": 41, "z_count": 41}}}),
    ("rcm-grid", {"robot": {"model": "ur5e"}, "candidates": {"grid": {"x_count": 21, "z_count": 21}}}),
    ("raven-sweep", {"sweep": {"alpha_deg": [25.0, 45.0, 65.0], "beta_deg": [45.0, 65.0], "phi_x_deg": [0.0],
                               "iso_min": [0.3, 0.5]}}),
    ("suture-sim", {}),
]


def measure(name: str, overrides: dict) -> tuple[float, float]:
    """(estimated single-core seconds, measured CPU seconds) of one config, kernels compiled first."""
    study = get_study(name)
    cfg = study.config_model.model_validate(overrides)
    study.warm_up(cfg)
    if name == "raven-sweep":
        from surgopt.kinematics.raven_workspace import clear_memo

        clear_memo()
    chunk = study.auto_chunk(cfg)
    t = time.process_time()
    for i in range(study.n_tasks(cfg, chunk)):
        study.compute_task(cfg, chunk, i)
    return study.estimate(cfg).seconds_one_core, time.process_time() - t


def main() -> None:
    print(f"{'study':<12} {'config':<60} {'estimate s':>10} {'measured s':>10} {'ratio':>6}")
    for name, overrides in CASES:
        est, cpu = measure(name, overrides)
        print(f"{name:<12} {str(overrides)[:60]:<60} {est:10.2f} {cpu:10.2f} {est / cpu:6.2f}")


if __name__ == "__main__":
    main()
