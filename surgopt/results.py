"""Finding stored runs from a key prefix or a config, and comparing tables with baselines.

Orchestration only: no kinematics. Studies are read through their ``Study`` declaration. One module (~420
lines): finding a run and comparing its rows (diff, check, export of one design) read the same run records.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from surgopt.config import load_config, study_key
from surgopt.errors import ConfigError, UsageError
from surgopt.store import Run, Store, manifest_of
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
    if len(fits) > 1:  # a study that extends another's configs claims only the files with its own section
        from surgopt.config import read_config_data

        data = read_config_data(path)
        fits = [(st, c) for st, c in fits if st.extends is None or st.config_section in data] or fits
    if len(fits) == 1:
        return fits[0]
    if not fits:
        raise ConfigError(str(path), "fits no study's config: " + " | ".join(errors))
    raise UsageError(f"{path}: fits several studies ({', '.join(s.name for s, _ in fits)}); add --study NAME")


def resolve_run(store: Store, ref: str | None, study_name: str | None = None):
    """(study, run) for a key prefix, a run's ``--name``, a config file, or (ref None or "latest") the latest run.
    ``study_name`` must be a registered study (it never reaches a path otherwise)."""
    if ref == "latest":
        ref = None
    if study_name is not None and study_name not in STUDIES:
        raise UsageError(f"--study: unknown study {study_name[:80]!r} (one of {', '.join(STUDIES)})")
    if ref is not None and Path(ref).is_file():
        study, cfg = study_of_config(Path(ref), study_name)
        run = store.open(study.name, study_key(study.name, cfg, study.kernel_version))
        if run is None:
            raise UsageError(f"{ref}: no stored {study.name} run for this config in {store.root}; "
                             f"run `surgopt {study.name} {ref}` first")
        return study, run
    runs = store.runs(study_name)
    if ref is not None:
        named = [r for r in runs if r.manifest.get("name") == ref]
        runs = named[-1:] if named else [r for r in runs if r.key.startswith(ref)]  # a name: its latest run
        if not runs:
            from surgopt.errors import StoreError
            from surgopt.store import folder_study_key

            for path, why in store.unreadable(study_name):
                if folder_study_key(path)[1].startswith(ref):
                    raise StoreError(f"{path}: {why}; `surgopt runs rm {ref}` deletes it")
            raise UsageError(f"{ref}: neither a config file, a run's name nor the key prefix of a run in {store.root}")
        if len(runs) > 1:
            raise UsageError(f"{ref}: matches {len(runs)} runs; give more of the key")
    if not runs:
        broken = store.unreadable(study_name)
        extra = f" ({len(broken)} with an unusable manifest: see `surgopt runs`)" if broken else ""
        raise UsageError(f"no runs in {store.root}{extra}")
    run = runs[-1]
    return study_of_run(run), run


def study_of_run(run: Run):
    """The declared study a stored run belongs to; StoreError for a study this surgopt does not have."""
    from surgopt.errors import StoreError

    if run.study not in STUDIES:
        raise StoreError(f"{run.path}: a run of study {run.study!r}, which this surgopt does not have "
                         f"(one of {', '.join(STUDIES)})")
    return get_study(run.study)


def require_complete(store: Store, run: Run, allow_partial: bool = False) -> Run:
    """``run`` when it is complete (or ``allow_partial``); else a StoreError that says how much of it is there,
    whether it is being written, and how to finish or read it: a partial table is never handed out unasked."""
    if run.complete or allow_partial:
        return run
    from surgopt.errors import StoreError

    who = store.holder(run.study, run.key)
    now = f", being written now by {who}" if who else ""
    raise StoreError(f"{run.study} run {run.key[:12]} is partial: {len(run.manifest['parts'])} of "
                     f"{run.manifest['n_tasks']} chunks stored ({run.rows:,} rows){now}; run {run.repair_hint()} "
                     f"to finish it, or pass --partial (Python: allow_partial=True) to read the rows there are")


def run_state(store: Store, run: Run) -> str:
    """complete | partial N/M | DAMAGED: part problem, with ", being written by pid N" while locked."""
    damaged = run.damaged()
    if damaged:
        state = f"DAMAGED: {damaged[0][0]} {damaged[0][1]}" + (f" (+{len(damaged) - 1} more)" if len(damaged) > 1 else "")
    elif run.complete:
        state = "complete"
    else:
        state = f"partial {len(run.manifest['parts'])}/{run.manifest['n_tasks']}"
    who = store.holder(run.study, run.key)
    return state + (f", being written by {who}" if who else "")


def run_records(store: Store, study: str | None = None) -> list[dict]:
    """One dict per run (snake_case keys): what ``surgopt runs`` shows, and each run's provenance."""
    out = []
    for r in store.runs(study):
        m = r.manifest
        out.append({"study": r.study, "key": r.key, "name": m.get("name"), "tags": m.get("tags", {}),
                    "config_name": m.get("config_name"),
                    "plan": (m.get("plan") or {}).get("name", "grid"), "rows": r.rows,
                    "state": run_state(store, r), "created": m.get("created"), "completed": m.get("completed"),
                    "kernel_version": m.get("kernel_version"), "n_tasks": m["n_tasks"], "chunk": m["chunk"],
                    "backend": m.get("backend"), "jobs": m.get("jobs"), "host": m.get("host"),
                    "wall_time_s": m.get("wall_time_s"), "versions": m.get("versions"), "path": str(r.path)})
    from surgopt.store import folder_study_key

    for path, why in store.unreadable(study):
        folder_study, folder_key = folder_study_key(path)
        out.append({"study": folder_study, "key": folder_key, "config_name": None, "rows": None,
                    "state": f"UNREADABLE: {why}", "path": str(path)})
    return out


def headline_of(store: Store, study, run: Run) -> dict:
    """A complete run's headline numbers: as its manifest keeps them (``Store.record_headline``), else from its
    summary (which reads its rows), then kept for the next reader. Empty for a run with no rows."""
    from surgopt.store import plain_headline

    kept = plain_headline(run.manifest.get("headline"))
    if kept is not None:
        return kept
    if not run.rows:
        return {}
    headline = study.summary(run.parts(study.schema_for(run.manifest["config"]))).headline
    store.record_headline(run, headline)
    return headline


def compare_records(store: Store, study) -> tuple[list[str], list[str], list[dict]]:
    """The complete runs of one study side by side (``surgopt runs --compare``, as ``dvc exp show``): the config
    keys whose values differ between them, the study's numeric headline metrics, and one record per run."""
    records = []
    for r in store.runs(study.name):
        if not r.complete:
            continue
        headline = headline_of(store, study, r)
        records.append({"key": r.key, "name": r.manifest.get("name") or "", "plan": (r.manifest.get("plan") or {})
                        .get("name", "grid"), "config": flat_config(r.manifest["config"]), "headline": headline,
                        "created": r.manifest.get("created")})
    keys = sorted({k for rec in records for k in rec["config"]})
    varying = [k for k in keys if len({repr(rec["config"].get(k)) for rec in records}) > 1]
    metrics = [k for k in (records[0]["headline"] if records else {})
               if all(isinstance(rec["headline"].get(k), (int, float)) and not isinstance(rec["headline"].get(k), bool)
                      for rec in records)]
    return varying, metrics, sorted(records, key=lambda rec: rec["created"] or "")


def flat_config(config: dict, prefix: str = "") -> dict:
    """{"a": {"b": 1}} -> {"a.b": 1}: a config as dotted keys (what overrides name)."""
    out = {}
    for k, v in config.items():
        if isinstance(v, dict) and set(v) != {"start", "stop", "step"}:
            out.update(flat_config(v, f"{prefix}{k}."))
        else:
            out[f"{prefix}{k}"] = v
    return out


def config_of(study, run: Run):
    """A stored run's config, validated; StoreError when the manifest's config is not one of this study."""
    from pydantic import ValidationError

    from surgopt.errors import StoreError

    try:
        return study.config_model.model_validate(run.manifest["config"], context={"stored": True})
    except ValidationError as exc:
        first = exc.errors()[0]
        where = ".".join(str(p) for p in first["loc"]) or "(top level)"
        raise StoreError(f"{manifest_of(run.path)}: its config is not a valid {study.name} config "
                         f"({where}: {first['msg']}); delete the run (`surgopt runs rm {run.key[:12]}`)") from None


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

    from surgopt.outputs import checked
    from surgopt.store import atomic_write

    path = checked(path, "--baseline")  # never onto the store's own files
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write(path, lambda tmp: pq.write_table(table.sort_by([(k, "ascending") for k in keys]), tmp,
                                                  compression="zstd"))


#: Decimals a design's identity columns are rounded to before two runs are joined on them (port-place: 1e-6 mm).
MATCH_DECIMALS = 6


def diff_runs(store: Store, ref_a: str, ref_b: str, study_name: str | None = None, top: int = 5) -> dict:
    """Two runs of one study compared: differing config fields, per-metric changes on the rows joined
    by the key columns, the most changed rows by the objective, the best design of each.

    The rows are joined by Arrow's hash join on the key columns alone (as integers of 10^-MATCH_DECIMALS), and
    each metric is compared through the joined row positions, one column at a time: two 2.2 M-row port-place
    runs took 17 s and 5 GB through a pandas merge of the whole tables (issue 42 item 5)."""
    sa, ra = resolve_run(store, ref_a, study_name)
    sb, rb = resolve_run(store, ref_b, study_name)
    if sa.name != sb.name:
        raise UsageError(f"{ref_a} is a {sa.name} run and {ref_b} a {sb.name} run: diff compares runs of one study")
    fa, fb = flat_config(ra.manifest["config"]), flat_config(rb.manifest["config"])
    config = {k: (fa.get(k), fb.get(k)) for k in dict.fromkeys([*fa, *fb]) if fa.get(k) != fb.get(k)}
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(2) as pool:  # the two runs read at once (Parquet's decoding releases the GIL)
        a, b = pool.map(lambda sr: sr[1].read_table(sr[0].schema_for(sr[1].manifest["config"])), ((sa, ra), (sb, rb)))
    keys, index_only, rounded = list(sa.key_columns), [], False
    if sa.design_identity is not None:  # enumerations differ between runs: join on what the design is
        ka, ia = sa.design_identity(ra.manifest["config"])
        kb, ib = sb.design_identity(rb.manifest["config"])
        if ka != kb:
            raise UsageError(f"the runs' designs are not alike ({', '.join(ka)} against {', '.join(kb)}): diff "
                             f"compares runs whose designs have the same parts")
        keys, index_only, rounded = list(ka), [c for c in dict.fromkeys([*ia, *ib]) if c in a.column_names], True
    pos_a, pos_b, only_a, only_b = _joined_positions(a, b, keys, rounded)
    key_values = {k: _key_values(a[k].to_numpy(zero_copy_only=False), rounded) for k in keys}
    metrics, deltas = {}, {}
    for c in a.column_names if pos_a.size else []:  # no layout in common: nothing to compare row by row
        if c in keys or c in index_only or c not in b.column_names or not _is_number(a.schema.field(c).type):
            continue
        x = a[c].to_numpy(zero_copy_only=False).astype(float)[pos_a]
        d = b[c].to_numpy(zero_copy_only=False).astype(float)[pos_b] - x
        deltas[c] = d
        finite = d[~np.isnan(d)]
        metrics[c] = {"changed": int(np.count_nonzero(np.abs(finite) > 0)),
                      "max_abs": float(np.abs(finite).max()) if finite.size else (0.0 if not d.size else float("nan")),
                      "mean": float(finite.mean()) if finite.size else (0.0 if not d.size else float("nan"))}
    # the objective a user reads (port-place: the cost of the feasible layouts, least first), else the study's
    objective, least = (sa.reported_objective[0], sa.reported_objective[1] == "minimize") if sa.reported_objective \
        else (sa.objective or next(iter(metrics), None), False)
    worst, best = [], {}
    if objective is not None and pos_a.size:
        oa = a[objective].to_numpy(zero_copy_only=False)[pos_a]
        ob = b[objective].to_numpy(zero_copy_only=False)[pos_b]
        change = np.abs(deltas[objective]) if objective in deltas else np.abs(ob.astype(float) - oa.astype(float))
        order = np.argsort(np.where(np.isnan(change), np.inf, -change), kind="stable")[:top]  # largest, NaN last
        worst = [{**{k: _plain(key_values[k][pos_a[i]]) for k in keys}, f"{objective}_a": _plain(oa[i]),
                  f"{objective}_b": _plain(ob[i])} for i in order]
    if objective is not None:  # the best of each, also (above all) when no layout is in both
        show = keys + [c for c in dict.fromkeys([objective, *a.column_names]) if c not in keys][:9]
        feasible = sa.feasible_mask if sa.reported_objective else None
        best = {"a": _best_row(a, objective, show, key_values, least, feasible), "b": _best_row(
            b, objective, show, {k: _key_values(b[k].to_numpy(zero_copy_only=False), rounded) for k in keys}, least,
            feasible)}
    return {"study": sa.name, "a": {"key": ra.key, "config_name": ra.manifest.get("config_name")},
            "b": {"key": rb.key, "config_name": rb.manifest.get("config_name")}, "config": config,
            "key_columns": keys, "rows_joined": int(pos_a.size), "rows_only_a": only_a, "rows_only_b": only_b,
            "metrics": metrics, "objective": objective, "worst": worst, "best": best,
            "best_among": "feasible" if sa.reported_objective else "all"}


def _is_number(t) -> bool:
    import pyarrow as pa

    return (pa.types.is_integer(t) or pa.types.is_floating(t)) and not pa.types.is_boolean(t)


def _key_values(values: np.ndarray, rounded: bool) -> np.ndarray:
    """A key column as joined and shown: rounded to MATCH_DECIMALS for a design's identity (coordinates)."""
    return np.round(values.astype(float), MATCH_DECIMALS) + 0.0 if rounded else values


def _joined_positions(a, b, keys: list[str], rounded: bool):
    """(row positions in a, the matching positions in b, rows only in a, rows only in b) of the inner join on
    ``keys``, in the keys' ascending order (as a sorted merge gives them). Coordinates are joined as integers of
    10^-MATCH_DECIMALS (0.0 and -0.0 alike; no float compared for equality)."""
    import pyarrow as pa

    def side(t, name):
        cols = {}
        for k in keys:
            v = t[k].to_numpy(zero_copy_only=False)
            cols[k] = pa.array(np.rint(v.astype(float) * 10.0 ** MATCH_DECIMALS).astype(np.int64)) if rounded \
                else t[k].combine_chunks()
        cols[name] = pa.array(np.arange(t.num_rows, dtype=np.int64))
        return pa.table(cols)

    joined = side(a, "__a").join(side(b, "__b"), keys=keys, join_type="full outer")
    ia, ib = (joined[n].to_numpy(zero_copy_only=False) for n in ("__a", "__b"))
    has_a, has_b = ~np.isnan(ia.astype(float)), ~np.isnan(ib.astype(float))
    both = has_a & has_b
    pos_a, pos_b = ia[both].astype(np.int64), ib[both].astype(np.int64)
    # by the keys (the first most significant), then by each run's own row order
    order = np.lexsort([pos_b, pos_a] + [joined[k].to_numpy(zero_copy_only=False)[both] for k in reversed(keys)])
    return pos_a[order], pos_b[order], int(np.count_nonzero(has_a & ~has_b)), int(np.count_nonzero(has_b & ~has_a))


def _best_row(t, objective: str, show: list[str], key_values: dict, least: bool = False, feasible=None) -> dict:
    """The first row with the largest ``objective`` (``least``: the smallest; NaN skipped; ``feasible``: among the
    rows its mask keeps), its ``show`` columns (keys as joined)."""
    v = t[objective].to_numpy(zero_copy_only=False).astype(float)
    if feasible is not None:
        v = np.where(np.asarray(feasible(t), bool), v, np.nan)
    if np.isnan(v).all():
        return {}
    i = int(np.nanargmin(v) if least else np.nanargmax(v))
    return {c: _plain(key_values[c][i] if c in key_values else t[c][i].as_py()) for c in show}


def _plain(x):
    return x.item() if hasattr(x, "item") else x


def grid_best(store: Store, study, cfg, column: str, direction: str, feasible_only: bool = False):
    """(label, value) of ``column``'s best (``direction``) over the same config's own grid (its [search] replaced
    by the study's default), if ``store`` holds that run complete; over its feasible designs with
    ``feasible_only``. What a search's convergence is drawn against (``plot``, ``report``)."""
    try:
        grid_cfg = cfg.model_copy(update={"search": study.config_model.model_fields["search"].default})
        run = store.open(study.name, study_key(study.name, grid_cfg, study.kernel_version))
    except Exception:  # noqa: BLE001 - no reference then
        return None
    if run is None or not run.complete:
        return None
    values = run.parts(study.schema_for(run.manifest["config"])).column(
        column, where=study.feasible_mask if feasible_only else None)
    if not values.size:
        return None
    return (f"the grid's best ({len(values):,} {'feasible ' if feasible_only else ''}designs)",
            float(values.max() if direction == "maximize" else values.min()))


def export_design(store: Store, ref: str, design: int, fmt: str, study_name: str | None = None
                  ) -> tuple[str, list[str]]:
    """One design's row of a run in a format its study declares (``Study.exports``): the text to write, and the
    notes to say beside it (a design whose row is not feasible: written as computed, not a layout to use). A
    UsageError naming what is wrong: a study without that format, a design not among the rows."""
    import pyarrow.compute as pc

    st, r = resolve_run(store, ref, study_name)
    require_complete(store, r, False)
    if fmt not in st.exports:
        known = ", ".join(st.exports) or "none"
        raise UsageError(f"--format {fmt}: not a format of {st.name} runs (csv, parquet, json; its own: {known})")
    key = st.key_columns[0]
    rows = [t.filter(pc.equal(t[key], design)) for t in r.parts(st.schema_for(r.manifest["config"]))]
    rows = [t for t in rows if t.num_rows]
    if not rows:
        raise UsageError(f"--design {design}: no row of run {r.key[:12]} has {key} = {design}")
    row = rows[0].to_pylist()[0]
    notes = ([f"note: design {design} is not feasible in run {r.key[:12]} (its row's feasible is false); the file "
              f"describes it as computed, not as a layout to use"] if row.get("feasible") is False else [])
    return st.exports[fmt](config_of(st, r), {**row, "run_key": r.key}), notes
