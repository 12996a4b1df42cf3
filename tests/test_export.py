"""``surgopt export``'s CSV, written part by part by Arrow (issue 42 item 5), held to Python's own ``csv`` module
writing ``repr`` of every float (what the export wrote before, through pandas): the same cells, the same
floats read back, and pandas reading the file back to the table it came from, dtypes included."""
from __future__ import annotations

import csv
import io
import math

import numpy as np
import pandas as pd
import pyarrow as pa
from hypothesis import given, settings
from hypothesis import strategies as st

from surgopt.export import csv_lines

FLOATS = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10**17, 10**17).map(float),
                   st.sampled_from([0.0, -0.0, 1e-300, 4.469429938361067e-09, 1e-5, 72.0, -144.0, 1e16, 0.1,
                                    float("inf"), float("-inf")]),
                   st.none())
TEXT = st.one_of(st.text(alphabet=st.sampled_from(list('ab ,"\n\r;é')), max_size=6), st.none())


def python_csv(rows: list[list]) -> str:
    """The rows as Python's csv module writes them, floats as repr, NaN and None empty, booleans True/False."""
    def cell(v):
        if v is None or (isinstance(v, float) and math.isnan(v)):
            return ""
        return repr(v) if isinstance(v, float) else str(v)

    out = io.StringIO()
    # "\r\n": the writer quotes a field holding any character of the line terminator, so a lone \r is quoted too
    csv.writer(out, lineterminator="\r\n").writerows([[cell(v) for v in row] for row in rows])
    return out.getvalue()


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(FLOATS, st.one_of(st.booleans(), st.none()), st.integers(-2**40, 2**40), TEXT),
                min_size=1, max_size=12))
def test_csv_cells_are_what_python_writes(rows):
    """Every cell of ``csv_lines`` reads back (csv module) to what Python's writer gives for the same value:
    text, integers and booleans character for character, floats to the same float (Arrow's shortest form may
    spell an exponent differently: 1e-05 / 0.00001)."""
    table = pa.table({"x": pa.array([r[0] for r in rows], pa.float64()), "ok": pa.array([r[1] for r in rows]),
                      "n": pa.array([r[2] for r in rows], pa.int64()), "s": pa.array([r[3] for r in rows], pa.string())})
    ours = list(csv.reader(io.StringIO(bytes(csv_lines(table)).decode(), newline="")))
    theirs = list(csv.reader(io.StringIO(python_csv([list(r) for r in rows]), newline="")))
    assert len(ours) == len(theirs) == len(rows)
    for a, b in zip(ours, theirs):
        assert a[1:] == b[1:]
        assert (a[0] == b[0] == "") or float(a[0]) == float(b[0]) and ("." in a[0] or "e" in a[0] or "n" in a[0])


def test_pandas_reads_the_csv_back_as_the_table_was():
    """Integral floats keep their ".0" (a column of 72.0 and -144.0 reads back as floats, not integers), a float32
    is written as its own value, a dictionary column as its values; pandas' frame equals the table's exactly."""
    table = pa.table({"x_mm": pa.array([72.0, -144.0, 18.0]), "y": pa.array([0.1, np.nan, np.inf]),
                      "f32": pa.array([0.1, 2.5, 3.0], pa.float32()), "site": pa.array([1, 2, 3], pa.int32()),
                      "feasible": pa.array([True, False, True]),
                      "arm": pa.array(["PSM1", "a, b", 'say "hi"']).dictionary_encode()})
    header = ",".join(table.column_names) + "\n"
    back = pd.read_csv(io.BytesIO(header.encode() + bytes(csv_lines(table))))
    want = table.to_pandas()
    want["f32"] = want["f32"].astype(float)
    want["arm"] = want["arm"].astype(str)
    assert back["x_mm"].dtype == float and back["f32"].tolist() == [float(np.float32(0.1)), 2.5, 3.0]
    pd.testing.assert_frame_equal(back, want, check_dtype=False, check_exact=True)
    assert back.dtypes.astype(str).tolist()[:5] == ["float64", "float64", "float64", "int64", "bool"]


def pandas_diff(a, b, keys, index_only, objective, top=5, decimals=None, least_feasible=False):
    """``diff``'s metrics, worst rows and best rows the plain way (what surgopt did before issue 42 item 5): both
    tables whole in pandas, rounded keys, an outer merge."""
    a, b = a.to_pandas(), b.to_pandas()
    if decimals is not None:
        for t in (a, b):
            t[keys] = t[keys].round(decimals) + 0.0
    joined = a.merge(b, on=keys, how="outer", suffixes=("_a", "_b"), indicator=True)
    both = joined[joined["_merge"] == "both"]
    metrics = {}
    for c in a.columns:
        if c in keys or c in index_only or not np.issubdtype(a[c].dtype, np.number) or a[c].dtype == bool:
            continue
        d = both[f"{c}_b"].astype(float) - both[f"{c}_a"].astype(float)
        metrics[c] = {"changed": int((d.abs() > 0).sum()), "max_abs": float(d.abs().max()) if len(d) else 0.0,
                      "mean": float(d.mean()) if len(d) else 0.0}
    delta = (both[f"{objective}_b"] - both[f"{objective}_a"]).abs()
    rows = both.loc[delta.sort_values(ascending=False, kind="stable").index[:top]]
    worst = [{**{k: r[k] for k in keys}, f"{objective}_a": r[f"{objective}_a"], f"{objective}_b": r[f"{objective}_b"]}
             for _, r in rows.iterrows()]
    show = keys + [c for c in dict.fromkeys([objective, *a.columns]) if c not in keys][:9]
    if least_feasible:  # port-place: the feasible layout of least cost
        best = {side: t.loc[t[t["feasible"]][objective].idxmin(), show].to_dict() for side, t in (("a", a), ("b", b))}
    else:
        best = {"a": a.loc[a[objective].idxmax(), show].to_dict(), "b": b.loc[b[objective].idxmax(), show].to_dict()}
    return {"rows_joined": len(both), "rows_only_a": int((joined["_merge"] == "left_only").sum()),
            "rows_only_b": int((joined["_merge"] == "right_only").sum()), "metrics": metrics, "worst": worst,
            "best": best}


def same_diff(ours: dict, plain: dict) -> None:
    """Our diff equals the plain one: counts exactly, numbers to 1e-12 (a mean's summation order may differ)."""
    for k in ("rows_joined", "rows_only_a", "rows_only_b"):
        assert ours[k] == plain[k], k
    assert ours["metrics"].keys() == plain["metrics"].keys()
    for c, m in plain["metrics"].items():
        assert ours["metrics"][c]["changed"] == m["changed"], c
        np.testing.assert_allclose([ours["metrics"][c]["max_abs"], ours["metrics"][c]["mean"]],
                                   [m["max_abs"], m["mean"]], rtol=1e-12, atol=1e-12, err_msg=c)
    assert [{k: float(v) for k, v in r.items()} for r in ours["worst"]] == \
        [{k: float(v) for k, v in r.items()} for r in plain["worst"]]
    for side in ("a", "b"):
        assert {k: float(v) for k, v in ours["best"][side].items()} == \
            {k: float(v) for k, v in plain["best"][side].items()}


def test_diff_equals_a_plain_pandas_merge(monkeypatch, tmp_path):
    """Two toy runs whose designs overlap in part (i = 0..29 against 0..19, other values): ``diff_runs`` (Arrow's
    join, column by column) gives what a pandas merge of the whole tables gives."""
    from surgopt.results import diff_runs
    from surgopt.runner import run_study
    from surgopt.store import Store
    from surgopt.studies import STUDIES, get_study

    monkeypatch.setitem(STUDIES, "toy", "toy_study")
    toy = get_study("toy")
    store = Store(tmp_path)
    for cfg in (toy.config_model(n=30), toy.config_model(n=20, offset=-4.5)):
        run_study(toy, cfg, config_name="t", store=store, jobs=1, quiet=True)
    ra, rb = sorted(store.runs("toy"), key=lambda r: -r.rows)
    ours = diff_runs(store, ra.key, rb.key)
    plain = pandas_diff(ra.read_table(toy.schema()), rb.read_table(toy.schema()), ["i"], [], "square")
    assert plain["rows_only_a"] == 10 and plain["metrics"]["x"]["changed"] == 20  # the premise: they differ
    same_diff(ours, plain)


def test_an_export_says_how_far_it_is_past_two_seconds_and_its_size_at_the_end(tmp_path):
    """#56 item 5: a 2.4 M-row CSV export (1.33 GB) ran a minute with no word and ended with no size. Progress
    speaks once an export has taken PROGRESS_AFTER_S, then every PROGRESS_EVERY_S (a clock the test moves), with
    rows, share and bytes; the closing line gives the file's size."""
    from pathlib import Path

    from surgopt.export import PROGRESS_AFTER_S, PROGRESS_EVERY_S, Progress

    from conftest import invoke

    BASE = Path(__file__).parent / "baselines"
    now = [0.0]
    said = []
    p = Progress(2_400_000, said.append, clock=lambda: now[0])
    for _ in range(10):  # ten parts of 240,000 rows and 130 MB, 0.9 s apart
        now[0] += 0.9
        p.add(240_000, 130_000_000)
    assert now[0] > PROGRESS_AFTER_S + PROGRESS_EVERY_S  # the premise: long enough for two lines
    assert said == ["export: 720,000 of 2,400,000 rows (30 %), 390 MB written ...",
                    "export: 2,160,000 of 2,400,000 rows (90 %), 1,170 MB written ..."]
    quiet = Progress(10, None, clock=lambda: 1e9)
    quiet.add(10)
    assert quiet.said == 0
    code, out = invoke("rcm-grid", BASE / "rcm_small.toml", "--store", tmp_path / "s", "--quiet")
    assert code == 0
    code, out = invoke("export", "latest", "--store", tmp_path / "s", "--format", "csv", "--out", tmp_path / "r.csv")
    size = (tmp_path / "r.csv").stat().st_size
    assert code == 0 and out.strip().endswith(f", {size / 1e6:,.1f} MB)"), out
