"""Issue 53: port-place's rows held to small baselines of every variant while its house is rebuilt.

Each config in ``tests/baselines/port_variants/`` is one variant (the Si cart, three PSMs storing only the feasible
rows, serial PA10 arms, a mesh patient, a searched docking roll, a searched cart pose; the default Classic cart is
``tests/baselines/port_small``); its Parquet file holds the rows main computed before the redesign began
(``surgopt check CONFIG --baseline FILE --write``). After every move each row's every column must be the same
(keys exactly, floats to 1e-9 relative). A baseline changes only in a commit that says why."""
from pathlib import Path

import pyarrow.parquet as pq
import pytest

from conftest import invoke

HERE = Path(__file__).parent / "baselines" / "port_variants"
VARIANTS = sorted(p.stem for p in HERE.glob("*.toml"))


def test_every_variant_has_its_baseline_and_they_stay_small():
    assert set(VARIANTS) == {"si", "three_psms", "pa10", "mesh", "roll_search", "cart_search"}
    assert all((HERE / f"{v}.parquet").is_file() for v in VARIANTS)
    assert sum(p.stat().st_size for p in HERE.iterdir()) < 400_000
    for v in VARIANTS:
        assert 10 <= pq.read_metadata(HERE / f"{v}.parquet").num_rows <= 500


@pytest.mark.parametrize("variant", VARIANTS)
def test_the_variant_reproduces_its_baseline(tmp_path, variant):
    code, output = invoke("check", HERE / f"{variant}.toml", "--baseline", HERE / f"{variant}.parquet",
                          "--store", tmp_path / "s", "--jobs", "1")
    assert code == 0 and "OK:" in output, output


def test_a_changed_row_fails_the_check(tmp_path):
    """The premise: the check can fail (a baseline whose cost moved by 1e-6 is refused)."""
    import numpy as np
    import pyarrow as pa

    t = pq.read_table(HERE / "mesh.parquet")
    cost = t["cost"].to_numpy().copy()
    cost[int(np.argmax(np.abs(cost)))] *= 1 + 1e-6
    bad = tmp_path / "bad.parquet"
    pq.write_table(t.set_column(t.column_names.index("cost"), "cost", pa.array(cost)), bad)
    code, output = invoke("check", HERE / "mesh.toml", "--baseline", bad, "--store", tmp_path / "s", "--jobs", "1")
    assert code == 1 and "value(s) differ" in output
