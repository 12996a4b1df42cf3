"""Finding stored runs from a key prefix or a config, and comparing tables with baselines.

Orchestration only: no kinematics. Studies are read through their ``Study`` declaration.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from surgopt.config import load_config, study_key
from surgopt.errors import ConfigError, UsageError
from surgopt.store import Run, Store
from surgopt.studies import STUDIES, get_study


def study_of_config(path: Path, study_name: str | None):
    """(study, validated config) for a config file; the study is inferred when unambiguous."""
    if study_name is not None:
        if study_name not in STUDIES:
            raise UsageError(f"--study: unknown study {study_name!r} (one of {', '.join(STUDIES)})")
        study = get_study(study_name)
        return study, load_config(path, study.config_model)
    fits, errors = [], []
    for name in STUDIES:
        study = get_study(name)
        try:
            fits.append((study, load_config(path, study.config_model)))
        except ConfigError as exc:
            if "file not found" in str(exc) or "not valid" in str(exc) or "unknown config format" in str(exc):
                raise
            errors.append(str(exc))
    if len(fits) == 1:
        return fits[0]
    if not fits:
        raise ConfigError(str(path), "fits no study's config: " + " | ".join(errors))
    raise UsageError(f"{path}: fits several studies ({', '.join(s.name for s, _ in fits)}); add --study NAME")


def resolve_run(store: Store, ref: str | None, study_name: str | None = None):
    """(study, run) for a key prefix, a config file, or (ref None) the latest run."""
    if ref is not None and Path(ref).is_file():
        study, cfg = study_of_config(Path(ref), study_name)
        run = store.open(study.name, study_key(study.name, cfg, study.kernel_version))
        if run is None:
            raise UsageError(f"{ref}: no stored {study.name} run for this config in {store.root}; "
                             f"run `surgopt {study.name} {ref}` first")
        return study, run
    runs = store.runs(study_name)
    if ref is not None:
        runs = [r for r in runs if r.key.startswith(ref)]
        if not runs:
            raise UsageError(f"{ref}: neither a config file nor the key prefix of a run in {store.root}")
        if len(runs) > 1:
            raise UsageError(f"{ref}: matches {len(runs)} runs; give more of the key")
    if not runs:
        broken = store.unreadable(study_name)
        extra = f" ({len(broken)} with an unusable manifest: see `surgopt runs`)" if broken else ""
        raise UsageError(f"no runs in {store.root}{extra}")
    run = runs[-1]
    return get_study(run.study), run


def config_of(study, run: Run):
    return study.config_model.model_validate(run.manifest["config"])


@dataclass
class Difference:
    column: str
    key: tuple
    baseline: object
    current: object
    rel: float


def compare_tables(current, baseline, keys, rtol: float, atol: float):
    """Differences between two tables sorted by their key columns.

    Key columns and non-float columns must be equal; float columns within
    |a - b| <= atol + rtol |b| (NaN equals NaN). Returns (problems, diffs):
    structural problems (columns, row counts) and per-value differences,
    worst first. Works on plain Python/numpy values, whatever pandas' dtypes.
    """
    import pyarrow as pa

    problems = []
    if set(current.column_names) != set(baseline.column_names):
        problems.append(f"columns differ: only now {sorted(set(current.column_names) - set(baseline.column_names))}, "
                        f"only in baseline {sorted(set(baseline.column_names) - set(current.column_names))}")
        return problems, []
    if current.num_rows != baseline.num_rows:
        problems.append(f"row count differs: {current.num_rows} now, {baseline.num_rows} in the baseline")
        return problems, []
    sort = [(k, "ascending") for k in keys]
    a, b = current.sort_by(sort), baseline.sort_by(sort)
    keyvals = list(zip(*[a[k].to_pylist() for k in keys]))
    diffs = []
    for name in a.column_names:
        ca, cb = a[name], b[name]
        if pa.types.is_floating(ca.type) and name not in keys:
            x = ca.to_numpy(zero_copy_only=False).astype(float)
            y = cb.to_numpy(zero_copy_only=False).astype(float)
            bad = ~(np.isclose(x, y, rtol=rtol, atol=atol) | (np.isnan(x) & np.isnan(y)))
            for i in np.flatnonzero(bad):
                rel = abs(x[i] - y[i]) / max(abs(y[i]), atol, 1e-300)
                diffs.append(Difference(name, keyvals[i], y[i], x[i], rel))
        else:
            x, y = ca.to_pylist(), cb.to_pylist()
            for i in (i for i in range(len(x)) if x[i] != y[i]):
                diffs.append(Difference(name, keyvals[i], y[i], x[i], float("inf")))
    diffs.sort(key=lambda d: -d.rel)
    return problems, diffs


def write_baseline(table, keys, path: Path) -> None:
    """The table sorted by its key columns, written atomically as a Parquet baseline."""
    import pyarrow.parquet as pq

    from surgopt.store import atomic_write

    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(path, lambda tmp: pq.write_table(table.sort_by([(k, "ascending") for k in keys]), tmp,
                                                  compression="zstd"))
