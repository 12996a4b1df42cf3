"""``Parts.scan`` reading only the objective and the feasibility columns, then the parts that hold the top rows
(``where_columns``), held to its one pass over whole parts; each study's ``feasible_columns`` held to its mask."""
import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from surgopt.parts import Parts
from surgopt.studies import STUDIES, get_study

from conftest import HERE


def _parts(tables):
    read = {"whole": 0}

    def tables_of(columns=None, which=None):
        for i, t in enumerate(tables):
            if which is not None and i not in which:
                continue
            if columns is None:
                read["whole"] += 1
            yield t if columns is None else t.select(columns)

    return Parts(tables_of, sum(t.num_rows for t in tables), tables[0].schema), read


@settings(max_examples=60, deadline=None)
@given(sizes=st.lists(st.integers(0, 30), min_size=1, max_size=6), k=st.integers(1, 12), asc=st.booleans(),
       seed=st.integers(0, 2 ** 16))
def test_the_narrow_scan_is_the_whole_scan(sizes, k, asc, seed):
    """Parts of any sizes (empty ones too), values with ties and NaN: the same top rows in the same order, the
    same column and the same feasible values; whole parts read only where a top row lies."""
    rng = np.random.default_rng(seed)
    tables, start = [], 0
    for n in sizes:
        v = rng.integers(0, 5, n).astype(float)
        v[rng.random(n) < 0.1] = np.nan
        tables.append(pa.table({"id": start + np.arange(n), "cost": v, "feasible": rng.random(n) < 0.6,
                                "other": rng.random(n)}))
        start += n
    parts, read = _parts(tables)
    where = lambda t: t["feasible"].to_numpy(zero_copy_only=False)  # noqa: E731
    top_a, whole_a, kept_a = parts.scan("cost", k, asc, where)
    assert read["whole"] == len(tables)  # the premise: the one pass reads every part whole
    read["whole"] = 0
    top_b, whole_b, kept_b = parts.scan("cost", k, asc, where, where_columns=("feasible",))
    assert str(top_b.to_pylist()) == str(top_a.to_pylist())  # as text: NaN != NaN
    np.testing.assert_array_equal(whole_b, whole_a)
    np.testing.assert_array_equal(kept_b, kept_a)
    holding = {i for i, t in enumerate(tables) if set(t["id"].to_pylist()) & set(top_b["id"].to_pylist())}
    assert read["whole"] == len(holding) <= k  # whole parts read: those that hold a top row, no other


@pytest.mark.parametrize("name", sorted(STUDIES))
def test_a_studys_feasible_columns_are_what_its_mask_reads(name):
    """Each study's ``feasible_columns`` give its mask's answer on a run's rows (a baseline's, or rcm-grid's for
    rcm-track, which shares its rows' schema): the mask on those columns alone equals it on every column."""
    study = get_study(name)
    base = {"rcm-grid": "rcm_small", "rcm-track": "rcm_small", "raven-sweep": "raven_small",
            "suture-sim": "suture_small", "port-place": "port_small"}[name]
    table = pq.read_table(HERE / "baselines" / f"{base}.parquet")
    if study.feasible_columns is None:
        pytest.skip(f"{name} reads its table otherwise than by column names (its mask runs on whole parts)")
    whole = np.asarray(study.feasible_mask(table), bool)
    assert 0 < whole.sum() < len(whole)  # the premise: the mask decides something
    np.testing.assert_array_equal(np.asarray(study.feasible_mask(table.select(list(study.feasible_columns))), bool),
                                  whole)


@settings(max_examples=40, deadline=None)
@given(sizes=st.lists(st.integers(0, 30), min_size=1, max_size=6), k=st.integers(1, 12), asc=st.booleans(),
       seed=st.integers(0, 2 ** 16))
def test_the_top_among_feasible_rows_is_pandas_sort_of_the_feasible_rows(sizes, k, asc, seed):
    """#56 item 9: summarize ranks port-place's layouts by the cost of the feasible ones (``top_where``), not by the
    penalised score of all: both scans give pandas' stable sort of the feasible rows by cost (ties in row order)."""
    import pandas as pd

    rng = np.random.default_rng(seed)
    tables, start = [], 0
    for n in sizes:
        tables.append(pa.table({"id": start + np.arange(n), "cost": rng.integers(0, 5, n).astype(float),
                                "feasible": rng.random(n) < 0.4}))
        start += n
    parts, _ = _parts(tables)
    df = pa.concat_tables(tables).to_pandas()
    want = df[df["feasible"]].sort_values("cost", ascending=asc, kind="stable").head(k)["id"].tolist()
    where = lambda t: t["feasible"].to_numpy(zero_copy_only=False)  # noqa: E731
    for columns in (None, ("feasible",)):
        top = parts.scan("cost", k, asc, where, where_columns=columns, top_where=True)[0]
        assert top["id"].to_pylist() == want and all(top["feasible"].to_pylist())
