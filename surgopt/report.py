"""Summaries of stored runs as tables, and their rendering as CSV, JSON or Markdown.

Knows studies only through the ``Study`` protocol (name, objective, key columns, summary,
feasible_mask); figures belong to each study (``surgopt/studies/figures``)."""
from __future__ import annotations

import json

import numpy as np

from surgopt.studies.plotting import columns

STATS = ("count", "min", "p25", "median", "p75", "max", "mean")


def sort_order(sort: str | None, study) -> tuple[str | None, bool]:
    """(column, ascending) of a --sort value: "name" ranks the largest first, "-name" the smallest (as a
    [search] objective's "-name" minimises); no value: the objective the study reports (``reported_objective``,
    e.g. port-place's cost, least first: ranked among the feasible rows, ``ranks_feasible``), else its objective,
    largest first."""
    if sort is None:
        if study.reported_objective is not None:
            column, direction = study.reported_objective
            return column, direction == "minimize"
        return study.objective, False
    return (sort[1:], True) if sort.startswith("-") else (sort, False)


def ranks_feasible(sort: str | None, study) -> bool:
    """Whether the top rows are drawn from the feasible rows only: by the study's reported objective (issue 56
    item 9: port-place's summary ranked every row by its penalised score, down to -605.9, not by the cost of the
    layouts one could use)."""
    return sort is None and study.reported_objective is not None and study.feasible_mask is not None


def top_table(study, parts, top: int = 10, sort: str | None = None):
    """The top rows as an Arrow table (full precision): what ``summarize --format csv`` writes; None for a
    study without an objective when no --sort is given."""
    column, ascending = sort_order(sort, study)
    if column is None or not parts.num_rows:
        return None
    check_sort_column(parts.schema, column)
    if ranks_feasible(sort, study):
        return parts.scan(column, top, ascending=ascending, where=study.feasible_mask,
                          where_columns=study.feasible_columns, top_where=True)[0]
    return parts.top(column, top, ascending=ascending)


def check_sort_column(schema, column: str) -> None:
    """UsageError unless ``column`` is a numeric (or boolean) column of the table: what --sort can rank by."""
    import pyarrow as pa

    from surgopt.errors import UsageError

    numeric = [f.name for f in schema if pa.types.is_integer(f.type) or pa.types.is_floating(f.type)
               or pa.types.is_boolean(f.type)]
    if column not in schema.names:
        raise UsageError(f"--sort: no column {column[:80]!r}; columns: {', '.join(schema.names)}")
    if column not in numeric:
        raise UsageError(f"--sort: {column!r} is not a number column; rank by one of: {', '.join(numeric)}")


def summary_sections(study, run, parts, top: int = 10, sort: str | None = None,
                     columns_shown: list[str] | None = None) -> list[tuple[str, list[str], list[list]]]:
    """Study-aware summary: header, top designs, objective statistics, feasibility, study tables.

    ``parts``: the run's rows (``surgopt.parts.Parts``, or one Arrow table), read part by part: memory
    holds one part, the top rows and the objective column, not the run.
    """
    from surgopt.parts import Parts

    if not isinstance(parts, Parts):
        parts = Parts.of_table(parts)
    done, total = len(run.manifest["parts"]), run.manifest["n_tasks"]
    state = "complete" if done == total else f"PARTIAL: {done} of {total} chunks stored (rerun the study to finish)"
    summary = run_summary(study, run, parts) if parts.num_rows else None
    head = [["study", study.name], ["key", run.key[:12]], ["config", run.manifest.get("config_name", "?")],
            ["rows", parts.num_rows], ["state", state], ["created", run.manifest.get("created", "?")]]
    head += [[k, v] for k, v in summary.feasibility.items()] if summary else []
    head += [["best on an edge", note] for note in run_edges(study, run, parts)]
    sections = [("run", ["field", "value"], head)]
    objective, ascending = sort_order(sort, study)
    if objective is not None and parts.num_rows:
        names_all = parts.schema.names
        check_sort_column(parts.schema, objective)
        among_feasible = ranks_feasible(sort, study)
        best, every, feasible = parts.scan(objective, top, ascending=ascending, where=study.feasible_mask,
                                            where_columns=study.feasible_columns, top_where=among_feasible)
        cols = columns(best)
        names = [c for c in names_all if cols[c].dtype != object or c in study.key_columns]
        more = ""
        if columns_shown:
            unknown = [c for c in columns_shown if c not in names_all]
            if unknown:
                from surgopt.errors import UsageError

                raise UsageError(f"--columns: no column {unknown[0][:80]!r}; columns: {', '.join(names_all)}")
            names = list(columns_shown)
        elif study.top_columns is not None:
            chosen = [c for c in study.top_columns(run.manifest["config"]) if c in names]
            if len(chosen) < len(names):
                names, more = chosen, f"; {len(names) - len(chosen)} more columns: --columns or --format json"
        sections.append((f"top {best.num_rows}{' feasible' if among_feasible else ''} by {objective}"
                         f"{' (smallest first)' if ascending else ''}"
                         f"{more if not columns_shown and study.top_columns is not None and more else ''}", names,
                         [[_fmt(cols[c][i]) for c in names] for i in range(best.num_rows)]))
        rows = []
        for label, v in (("all", every.astype(float)), ("feasible", feasible.astype(float))):
            if v.size:
                q = np.percentile(v, [0, 25, 50, 75, 100])
                rows.append([label, len(v)] + [_fmt(x) for x in q] + [_fmt(v.mean())])
        sections.append((f"distribution of {objective}", ["rows"] + list(STATS), rows))
    if summary and study.objective is None:
        for title, header, rows in summary.tables:
            sections.append((title, header, rows))
    front = search_front(study, run, parts)
    if front is not None:
        sections.append(front)
    return sections


def search_front(study, run, parts):
    """(title, header, rows) of the Pareto front of a multi-objective search run, else None."""
    from surgopt.results import config_of
    from surgopt.plans.search import pareto_front

    plan = study.search_plan(config_of(study, run)) if study.search_plan else None
    if plan is None or len(plan.objectives) < 2 or not parts.num_rows:
        return None
    table = parts.table()
    cols = [c for c, _ in plan.objectives]
    values = np.column_stack([table[c].to_numpy(zero_copy_only=False) for c in cols])
    feasible = feasible_rows(study, table)
    kept = np.flatnonzero(feasible)
    idx = kept[pareto_front(values[kept], [d for _, d in plan.objectives])]
    names = list(study.key_columns[:1]) + list(plan.space) + [c for c in cols if c not in plan.space]
    rows = sorted(([_fmt(table[c][int(i)].as_py()) for c in names] for i in idx), key=lambda r: r[-1])
    title = ("Pareto front of " + " vs ".join(f"{c} ({d[:3]})" for c, d in plan.objectives) + f": {len(idx)} designs"
             + ("" if feasible.all() else f" (of the {len(kept):,} feasible of {len(feasible):,} trials)"))
    return (title, names, rows)


def feasible_rows(study, table) -> np.ndarray:
    """Which rows the study counts feasible (every row when it declares no test): a Pareto front is of these, so
    that no design it could not build is on it."""
    if study.feasible_mask is None:
        return np.ones(table.num_rows, bool)
    return np.asarray(study.feasible_mask(table), bool)


#: A best design within this share of a dimension's range of a bound is on that edge of the box.
EDGE_SHARE = 1e-6


def edges_of_best(study, cfg, parts) -> list[str]:
    """What the closing report, ``summarize`` and a search say when the best design (by the study's objective)
    lies on an edge of the box the config explores: one line per dimension, with the field to widen."""
    if study.design_box is None or study.objective is None or not parts.num_rows:
        return []
    best = parts.top(study.objective, 1, where=study.feasible_mask)  # the best feasible design, if any
    if not best.num_rows or best[study.objective][0].as_py() is None:
        return []
    notes = []
    for e in study.design_box(cfg):
        if e.high <= e.low or e.column not in best.column_names:
            continue
        v = float(best[e.column][0].as_py())
        tol = EDGE_SHARE * (e.high - e.low)
        for bound, field, word in ((e.low, e.low_field, "lower"), (e.high, e.high_field, "upper")):
            if abs(v - bound) <= tol:
                notes.append(f"best design on the {word} edge of the box: {e.column} = {v:g} ({field}); "
                             f"widen it to see whether a better one lies beyond")
    return notes


def run_summary(study, run, parts):
    """``study.summary`` of a run's rows (``parts``: the run's own), kept beside the run once it is complete
    (``surgopt.derived``): the closing report, ``summarize`` and the API derive it once."""
    from surgopt.derived import derived
    from surgopt.studies import Summary

    def compute():
        s = study.summary(parts)
        return {"headline": s.headline, "feasibility": s.feasibility, "tables": s.tables}

    got = derived(run, "summary", compute)
    return Summary(got["headline"], got["feasibility"], [tuple(t) for t in got["tables"]])


def run_edges(study, run, parts) -> list[str]:
    """``best_edges`` of a run's rows, kept as ``run_summary`` is."""
    from surgopt.derived import derived

    return derived(run, "best_edges", lambda: best_edges(study, run, parts))


def run_sections(study, run, top: int = 10, sort: str | None = None,
                 columns_shown: list[str] | None = None) -> list:
    """``summary_sections`` of a stored run's own rows: derived once a run is complete, then kept beside it
    (``surgopt.derived``: ``summarize`` of a 2.2 M-row run reads no row the second time)."""
    from surgopt.derived import derived

    return derived(run, "summary_sections", lambda: summary_sections(
        study, run, run.parts(study.schema_for(run.manifest["config"])), top, sort, columns_shown),
        top=top, sort=sort, columns=columns_shown)


def run_record(study, run, top: int = 10, sort: str | None = None) -> dict:
    """``summary_record`` of a stored run's own rows, kept as ``run_sections`` is."""
    from surgopt.derived import derived

    return derived(run, "summary_record", lambda: summary_record(
        study, run, run.parts(study.schema_for(run.manifest["config"])), top, sort), top=top, sort=sort)


def summary_record(study, run, parts, top: int = 10, sort: str | None = None) -> dict:
    """``summarize --format json``: the same facts as ``summary_sections`` with stable snake_case keys and
    values at full precision."""
    from surgopt.parts import Parts

    if not isinstance(parts, Parts):
        parts = Parts.of_table(parts)
    done, total = len(run.manifest["parts"]), run.manifest["n_tasks"]
    summary = run_summary(study, run, parts) if parts.num_rows else None
    out = {"study": study.name, "key": run.key, "config_name": run.manifest.get("config_name"),
           "rows": parts.num_rows, "complete": done == total, "chunks_stored": done, "chunks": total,
           "created": run.manifest.get("created"),
           "feasibility": summary.feasibility if summary else {}, "headline": summary.headline if summary else {},
           "best_on_an_edge": run_edges(study, run, parts)}
    objective, ascending = sort_order(sort, study)
    if objective is not None and parts.num_rows:
        check_sort_column(parts.schema, objective)
        out["objective"] = objective
        out["ascending"] = ascending
        among_feasible = ranks_feasible(sort, study)
        best, every, feasible = parts.scan(objective, top, ascending=ascending, where=study.feasible_mask,
                                            where_columns=study.feasible_columns, top_where=among_feasible)
        out["top"] = best.to_pylist()
        out["distribution"] = {}
        for label, v in (("all", every.astype(float)), ("feasible", feasible.astype(float))):
            if v.size:
                q = np.percentile(v, [0, 25, 50, 75, 100])
                out["distribution"][label] = dict(zip(STATS, [int(v.size)] + [float(x) for x in q] + [float(v.mean())]))
    if summary and summary.tables:
        out["tables"] = [{"title": title, "header": header, "rows": rows} for title, header, rows in summary.tables]
    return out


def best_edges(study, run, parts) -> list[str]:
    """``edges_of_best`` for a stored run (its config read from its manifest)."""
    from surgopt.errors import StoreError
    from surgopt.results import config_of

    try:
        return edges_of_best(study, config_of(study, run), parts)
    except StoreError:  # a config this version no longer reads: no box to compare with
        return []


def _fmt(x):
    if isinstance(x, (float, np.floating)):
        return float(f"{x:.6g}")
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def render(sections, fmt: str) -> str:
    if fmt == "json":
        return json.dumps({title: [dict(zip(header, row)) for row in rows] for title, header, rows in sections},
                          indent=1, default=str)
    out = []
    for title, header, rows in sections:
        if fmt == "csv":
            import csv
            import io

            buf = io.StringIO()
            buf.write(f"# {title}\n")
            w = csv.writer(buf)
            w.writerow(header)
            w.writerows(rows)
            out.append(buf.getvalue())
        else:  # markdown
            cell = lambda v: str(v).replace("|", "\\|")  # noqa: E731
            out.append(f"### {title}\n\n| " + " | ".join(map(cell, header)) + " |\n|" + "---|" * len(header) + "\n"
                       + "".join("| " + " | ".join(map(cell, r)) + " |\n" for r in rows))
    return "\n".join(out)
