"""A cache hit answered from the recorded command line (``surgopt.hits``) and the Parquet footer read without
pyarrow (``surgopt.parquet_footer``)."""
import json
import subprocess
import sys

import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from surgopt.parquet_footer import footer_num_rows

CONFIG = """
[workspace]
points_per_side = 3
[candidates.grid]
x_min_m = 0.3
x_max_m = 0.7
x_count = 5
z_min_m = -0.5
z_max_m = 0.0
z_count = 4
"""
#: What a process that answered a command line had loaded of the heavy modules (the study's declaration, numpy,
#: pydantic, pyarrow): a ``python -c`` around ``surgopt.cli.run``.
PROBE = ("import sys; sys.argv = ['surgopt', *sys.argv[1:]]\nfrom surgopt.cli import run\ntry:\n    run()\n"
         "except SystemExit:\n    pass\nprint('LOADED', sorted(m for m in sys.modules if m.endswith('.study') or m in "
         "('numpy', 'pydantic', 'pyarrow')))")


def _surgopt(*args, cwd):
    r = subprocess.run([sys.executable, "-c", PROBE, *map(str, args)], capture_output=True, text=True, cwd=cwd,
                       check=True, env={"PATH": "/usr/bin:/bin", "COLUMNS": "200", "HOME": str(cwd),
                                        **_numba_env()})
    loaded = r.stdout.rstrip().splitlines()[-1]
    return r.stdout, r.stderr, loaded


def _numba_env():
    import os

    return {k: v for k, v in os.environ.items() if k.startswith(("NUMBA_", "SURGOPT_")) and k != "SURGOPT_STORE"}


def _report(out):
    """The closing report from its title on, its time left out."""
    lines = out.rstrip().splitlines()[:-1]
    start = next(i for i, x in enumerate(lines) if "rcm-grid (" in x)
    return [x for x in lines[start:] if "time_s" not in x]


def test_a_repeated_command_line_is_answered_without_loading_the_study(tmp_path):
    """The same plain command line twice: the second is answered from the store's record (the premise: the first
    recorded it, with the config file it read) without importing the study, numpy, pydantic or pyarrow, and
    prints the report the usual cache hit prints; any other option takes the usual way."""
    (tmp_path / "small.toml").write_text(CONFIG)
    store = tmp_path / "s"
    first, _, loaded = _surgopt("rcm-grid", "small.toml", "--store", store, cwd=tmp_path)
    assert "numpy" in loaded and "cache hit" not in first
    (record,) = (store / "_hits").glob("*.json")
    entry = json.loads(record.read_text())
    (run,) = (store / "study=rcm-grid").glob("key=*")
    assert run.name == f"key={entry['key']}" and [r for _, r, _ in entry["files"]] == [str(tmp_path / "small.toml")]
    second, _, loaded = _surgopt("rcm-grid", "small.toml", "--store", store, cwd=tmp_path)
    assert loaded == "LOADED []" and "cache hit: rcm-grid" in second
    usual, _, loaded = _surgopt("rcm-grid", "small.toml", "--store", store, "--jobs", "1", cwd=tmp_path)
    assert "numpy" in loaded and "cache hit: rcm-grid" in usual  # not a plain command line: the usual cache hit
    assert _report(second) == _report(usual) == _report(first) and len(_report(first)) > 10


def test_a_recorded_command_line_takes_the_usual_way_when_its_file_or_run_changed(tmp_path):
    """A recorded command line is answered from the record only while everything it rests on holds: a config file
    edited (a comment: the same run, found the usual way and recorded again), the derived numbers gone, a part
    damaged (the usual way finds it and recomputes), the run removed. Each time the usual path runs (the study
    loaded) and prints what it prints."""
    (tmp_path / "small.toml").write_text(CONFIG)
    store = tmp_path / "s"
    args = ("rcm-grid", "small.toml", "--store", store)
    first, _, _ = _surgopt(*args, cwd=tmp_path)
    (run,) = (store / "study=rcm-grid").glob("key=*")
    (tmp_path / "small.toml").write_text(CONFIG + "# edited\n")
    out, _, loaded = _surgopt(*args, cwd=tmp_path)
    assert "numpy" in loaded and "cache hit" in out  # the same config: the usual cache hit, recorded anew
    out, _, loaded = _surgopt(*args, cwd=tmp_path)
    assert loaded == "LOADED []" and _report(out) == _report(first)
    (run / "_derived.json").unlink()
    out, _, loaded = _surgopt(*args, cwd=tmp_path)
    assert "numpy" in loaded and _report(out) == _report(first)
    part = sorted(run.glob("part-*.parquet"))[0]
    data = bytearray(part.read_bytes())
    data[len(data) // 2] ^= 0xFF
    part.write_bytes(bytes(data))
    out, err, loaded = _surgopt(*args, cwd=tmp_path)
    assert "numpy" in loaded and "is damaged" in out + err and _report(out) == _report(first)
    import shutil

    shutil.rmtree(run)
    out, _, loaded = _surgopt(*args, cwd=tmp_path)
    assert "numpy" in loaded and "cache hit" not in out and _report(out) == _report(first)


def test_the_files_a_config_names_are_recorded_with_their_sha256(tmp_path):
    """``files.recording``: a config file and the file it names (port-place's target points) are noted with the
    sha256 of the bytes read, as absolute paths (what ``surgopt.hits`` checks before answering)."""
    import hashlib

    from surgopt.compose import variants
    from surgopt.files import recording
    from surgopt.studies import get_study

    (tmp_path / "pts.csv").write_text("0 -100 40\n10 -100 40\n")
    (tmp_path / "c.toml").write_text('[target]\nshape = "points"\npoints_file = "pts.csv"\n')
    with recording() as seen:
        variants(get_study("port-place"), str(tmp_path / "c.toml"), [], {})
    want = {str(tmp_path / f): hashlib.sha256((tmp_path / f).read_bytes()).hexdigest() for f in ("c.toml", "pts.csv")}
    assert {resolved: sha for _, resolved, sha in seen} == want


def test_a_retargeted_link_or_another_home_is_not_answered_from_the_record(tmp_path):
    """#55 item 3: a recorded command line resolves every path again as it was named: a config given through a
    link, or through a linked folder, retargeted to another config is not answered with the old run (the usual way
    runs the new one); a file a config names through a link (port-place's target points) is recorded with where
    the link led, and a retargeted link is a change; HOME (what '~' means) is part of the command's identity."""
    import os

    from surgopt import hits
    from surgopt.compose import variants
    from surgopt.files import recording
    from surgopt.studies import get_study

    store = tmp_path / "s"
    (tmp_path / "a.toml").write_text(CONFIG)
    (tmp_path / "b.toml").write_text(CONFIG.replace("x_count = 5", "x_count = 6"))
    (tmp_path / "c.toml").symlink_to(tmp_path / "a.toml")
    args = ("rcm-grid", "c.toml", "--store", store)
    _surgopt(*args, cwd=tmp_path)
    out, _, loaded = _surgopt(*args, cwd=tmp_path)
    assert loaded == "LOADED []"  # the premise: answered from the record
    (tmp_path / "c.toml").unlink()
    (tmp_path / "c.toml").symlink_to(tmp_path / "b.toml")
    out, _, loaded = _surgopt(*args, cwd=tmp_path)
    assert "numpy" in loaded and "cache hit" not in out and len(list((store / "study=rcm-grid").glob("key=*"))) == 2
    for name, count in (("d1", 7), ("d2", 8)):  # a linked config folder, as the record sees it (in this process)
        (tmp_path / name).mkdir()
        (tmp_path / name / "x.toml").write_text(CONFIG.replace("x_count = 5", f"x_count = {count}"))
    (tmp_path / "cfgs").symlink_to(tmp_path / "d1")
    here = os.getcwd()
    try:
        os.chdir(tmp_path)
        with recording() as seen:
            variants(get_study("rcm-grid"), "cfgs/x.toml", [], {})
        assert ("cfgs/x.toml", str(tmp_path / "d1" / "x.toml")) == seen[0][:2] and hits._unchanged(seen)
        (tmp_path / "cfgs").unlink()
        (tmp_path / "cfgs").symlink_to(tmp_path / "d2")
        assert not hits._unchanged(seen)
    finally:
        os.chdir(here)
    (tmp_path / "p1.csv").write_text("0 -100 40\n10 -100 40\n")
    (tmp_path / "p2.csv").write_text("0 -100 40\n10 -100 40\n")  # the same bytes: only the link tells them apart
    (tmp_path / "pts.csv").symlink_to(tmp_path / "p1.csv")
    (tmp_path / "t.toml").write_text('[target]\nshape = "points"\npoints_file = "pts.csv"\n')
    with recording() as seen:
        variants(get_study("port-place"), str(tmp_path / "t.toml"), [], {})
    assert (str(tmp_path / "pts.csv"), str(tmp_path / "p1.csv"), "") in seen and hits._unchanged(seen)
    (tmp_path / "pts.csv").unlink()
    (tmp_path / "pts.csv").symlink_to(tmp_path / "p2.csv")
    assert not hits._unchanged(seen)
    home = os.environ.get("HOME")
    try:
        os.environ["HOME"] = str(tmp_path)
        one = hits.command_sha256("rcm-grid", ["c.toml"])
        os.environ["HOME"] = str(tmp_path / "d1")
        assert hits.command_sha256("rcm-grid", ["c.toml"]) != one
    finally:
        if home is None:
            os.environ.pop("HOME", None)
        else:
            os.environ["HOME"] = home


def _parquet(table, **kw) -> bytes:
    sink = pa.BufferOutputStream()
    pq.write_table(table, sink, **kw)
    return sink.getvalue().to_pybytes()


COLUMNS = {
    "i": lambda n: pa.array(range(n), pa.int64()),
    "f": lambda n: pa.array([k * 0.5 for k in range(n)], pa.float64()),
    "b": lambda n: pa.array([k % 3 == 0 for k in range(n)]),
    "s": lambda n: pa.array([f"row {k}" for k in range(n)]).dictionary_encode(),
    "l": lambda n: pa.array([[k, k + 1] for k in range(n)], pa.list_(pa.int32())),
    "st": lambda n: pa.array([{"x": k, "y": str(k)} for k in range(n)]),
    "m": lambda n: pa.array([[("a", k)] for k in range(n)], pa.map_(pa.string(), pa.int64())),
}


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(n=st.integers(0, 3000), names=st.sets(st.sampled_from(sorted(COLUMNS)), min_size=1),
       group=st.integers(1, 5000), meta=st.booleans(), stats=st.booleans())
def test_the_footer_row_count_is_pyarrows(n, names, group, meta, stats):
    """Tables of every kind of column (nested lists, structs, maps, dictionaries), any number of row groups, with
    and without key-value metadata and statistics: the row count read without pyarrow is pyarrow's."""
    table = pa.table({k: COLUMNS[k](n) for k in sorted(names)})
    if meta:
        table = table.replace_schema_metadata({"config": json.dumps({"a": list(range(50))}), "x": "é"})
    data = _parquet(table, row_group_size=group, write_statistics=stats)
    assert footer_num_rows(data) == pq.read_metadata(pa.BufferReader(data)).num_rows == n


@pytest.mark.parametrize("cut", [1, 4, 8, 12, 40])
def test_a_footer_that_is_not_one_is_none(cut):
    """Bytes cut short, a wrong magic, a length past the start, a footer cut inside: None, never an exception."""
    data = _parquet(pa.table({"i": pa.array(range(100))}))
    assert footer_num_rows(data[:-cut]) is None
    assert footer_num_rows(data[:-4] + b"PAR0") is None
    assert footer_num_rows(data[:-8] + (len(data)).to_bytes(4, "little") + b"PAR1") is None
    length = int.from_bytes(data[-8:-4], "little")
    assert footer_num_rows(data[:-8 - length] + data[-8 - length:-8 - length + 3] + (3).to_bytes(4, "little")
                           + b"PAR1") is None
