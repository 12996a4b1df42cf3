"""The command line (surgopt/cli.py): stored tables equal library calls, cache hits, the store from the
environment, study flags, --help."""
import os
import subprocess
import sys

import numpy as np

from surgopt.config import load_config
from surgopt.runner import run_study
from surgopt.store import Store
from surgopt.studies.rcm_grid import study as S

from conftest import cli, single_run, single_table


def test_cli_stores_table_equal_to_library_call(tmp_path, small_cfg):
    store = tmp_path / "store"
    r = cli("rcm-grid", small_cfg, "--store", store, "--quiet", "--chunk-size", "7")
    assert "best_gii" in r.stdout
    cli_table = single_table(store)
    cfg = load_config(small_cfg, S.Config)
    lib = run_study(S.STUDY, cfg, config_name="x", store=Store(tmp_path / "lib"), jobs=1, quiet=True, chunk=1000)
    assert cli_table.equals(lib.table)
    # parts are plain Parquet: pandas reads them without surgopt
    import pandas as pd

    df = pd.concat([pd.read_parquet(f) for f in single_run(store).part_files()], ignore_index=True)
    assert np.array_equal(df["gii"].to_numpy(), cli_table["gii"].to_numpy())
    assert df["candidate_id"].dtype == np.int64 and df["feasible"].dtype == bool


def test_cache_hit_rewrites_nothing_and_says_so(tmp_path, small_cfg):
    store = tmp_path / "store"
    cli("rcm-grid", small_cfg, "--store", store, "--quiet")
    mtimes = {f: f.stat().st_mtime_ns for f in single_run(store).part_files()}
    r = cli("rcm-grid", small_cfg, "--store", store, "--quiet")
    assert "cache hit" in r.stdout
    assert {f: f.stat().st_mtime_ns for f in single_run(store).part_files()} == mtimes
    # --force recomputes (parts rewritten), same rows
    before = single_table(store)
    r = cli("rcm-grid", small_cfg, "--store", store, "--quiet", "--force")
    assert "cache hit" not in r.stdout
    assert single_table(store).equals(before)
    assert any(f.stat().st_mtime_ns != m for f, m in mtimes.items())


def test_store_from_environment(tmp_path, small_cfg):
    env = dict(os.environ, SURGOPT_STORE=str(tmp_path / "envstore"))
    cli("rcm-grid", small_cfg, "--quiet", env=env)
    assert len(Store(tmp_path / "envstore").runs()) == 1
    r = cli("runs", env=env)
    assert "rcm-grid" in r.stdout and "complete" in r.stdout and "small" in r.stdout


def test_cull_flag_is_a_separate_cached_study(tmp_path, small_cfg):
    store = tmp_path / "store"
    cli("rcm-grid", small_cfg, "--store", store, "--quiet")
    r = cli("rcm-grid", small_cfg, "--store", store, "--quiet", "--cull")
    assert "cache hit" not in r.stdout
    runs = Store(store).runs()
    assert len(runs) == 2
    full, cull = sorted(runs, key=lambda r: r.manifest["config"]["search"] == "cull")
    a, b = full.read_table(S.schema()), cull.read_table(S.schema())
    ga, gb = a["gii"].to_numpy(), b["gii"].to_numpy()
    assert ga.max() == gb[b["gii_is_exact"].to_numpy()].max()
    assert full.manifest["plan"] == {"name": "grid"} and cull.manifest["plan"] == {"name": "cull"}


#: what --help and ``import surgopt`` must not load: the kernels' compiler, Arrow, pandas, matplotlib
HEAVY_MODULES = ("numba", "llvmlite", "pyarrow", "pandas", "matplotlib")
#: imports surgopt (and the CLI), runs each ``--help`` in-process, then prints what it loaded and whether the
#: environment changed; numba is configured where a kernel is first imported, never before
HELP_PROBE = """
import os, sys, json, contextlib, io
before = dict(os.environ)
import surgopt, surgopt.cli
for args in (["--help"], ["rcm-grid", "--help"], ["suture-sim", "--help"], ["raven-sweep", "--help"],
             ["rcm-track", "--help"], ["runs", "--help"], ["summarize", "--help"]):
    sys.argv = ["surgopt", *args]
    with contextlib.redirect_stdout(io.StringIO()), contextlib.suppress(SystemExit):
        surgopt.cli.main()
print(json.dumps({"loaded": sorted(m for m in %r if m in sys.modules),
                  "env_changed": sorted(k for k in set(before) | set(os.environ) if before.get(k) != os.environ.get(k))}))
""" % (HEAVY_MODULES,)


def clean_env(tmp_path):
    """A shell's environment with nothing inherited from conftest (no NUMBA_*, no SURGOPT_*)."""
    return {"PATH": os.environ["PATH"], "HOME": str(tmp_path), "LANG": "C.UTF-8"}


def test_help_and_import_load_no_kernel_compiler_and_change_no_environment(tmp_path):
    """The commands are built from the studies' declarations (pydantic models and numpy helpers), but
    neither ``import surgopt.cli`` nor any ``--help`` loads numba/llvmlite, Arrow, pandas or matplotlib,
    or sets an environment variable: in a clean environment, on any CPU."""
    import json

    r = subprocess.run([sys.executable, "-c", HELP_PROBE], capture_output=True, text=True, check=True,
                       env=clean_env(tmp_path), cwd=tmp_path)
    probe = json.loads(r.stdout.strip().splitlines()[-1])
    assert probe == {"loaded": [], "env_changed": []}, probe


def test_importing_a_kernel_configures_numba_and_only_then(tmp_path):
    """The premise of the test above: importing the kernels is what loads numba and sets its cache folder."""
    code = ("import os, sys; import surgopt.kinematics.throat; "
            "print('numba' in sys.modules, os.environ.get('NUMBA_CACHE_DIR'))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                       env=clean_env(tmp_path), cwd=tmp_path)
    loaded, cache = r.stdout.split()
    assert loaded == "True" and cache == str(tmp_path / ".cache" / "surgopt" / "numba")


def test_help_texts():
    for args in (["--help"], ["rcm-grid", "--help"], ["runs", "--help"]):
        assert "Usage" in cli(*args).stdout
    assert "Global Isotropy Index" in cli("rcm-grid", "--help").stdout
    # #27 item 8: no "<bool>" metavar on surgopt's flags (Typer's own --help keeps its), -v after the subcommand
    for args in (["rcm-grid", "--help"], ["raven-sweep", "--help"], ["runs", "--help"], ["export", "--help"]):
        shown = [line for line in cli(*args, env={**os.environ, "COLUMNS": "200"}).stdout.splitlines()
                 if "<bool>" in line]
        assert all("--help" in line for line in shown), shown


def test_verbose_goes_before_or_after_the_subcommand(tmp_path):
    for args in (["-v", "rcm-grid"], ["rcm-grid", "-v"]):
        r = cli(*args, *SMALL_OVERRIDES, "--store", tmp_path, "-q")
        assert "surgopt: " in r.stderr and ("cache hit" in r.stderr or "parts of" in r.stderr), r.stderr


# --- a researcher's daily use: overrides, multirun, print-config, dry-run, export, diff, formats --------

SMALL_OVERRIDES = ["candidates.grid.x_count=5", "candidates.grid.z_count=4", "workspace.points_per_side=3"]


def test_overrides_multirun_table_and_cache_hits(tmp_path):
    store = tmp_path / "store"
    args = ["rcm-grid", *SMALL_OVERRIDES, "robot.tool_length_m=0.5,0.587", "--multirun", "--store", store, "-q"]
    r = cli(*args)
    assert "rcm-grid --multirun: 2 runs" in r.stdout and "robot.tool_length_m" in r.stdout
    assert len(Store(store).runs()) == 2
    again = cli(*args)
    assert again.stdout.count("cache hit") == 2
    # an override equal to the default: the same run as the embedded default with the other overrides
    assert "cache hit" in cli("rcm-grid", *SMALL_OVERRIDES, "robot.tool_length_m=0.587", "--store", store, "-q").stdout
    bad = cli("rcm-grid", "robot.tool_length_m=-1", "--store", tmp_path / "none", check=False)
    assert bad.returncode == 2 and "robot.tool_length_m: Input should be greater than 0" in bad.stderr
    assert not (tmp_path / "none").exists()
    assert cli("rcm-grid", "robot.tool_length_m=0.5,0.6", "--store", tmp_path / "none", check=False).returncode == 2


def test_runs_are_named_and_compared_side_by_side(tmp_path):
    """#27 item 4: --name labels a run (not in its key: a cache hit takes the new name), `runs` shows names and
    plans, and `runs --compare` lists the config values that differ between runs beside their headline metrics."""
    import json

    store = tmp_path / "store"
    cli("rcm-grid", *SMALL_OVERRIDES, "robot.tool_length_m=0.5,0.587", "--multirun", "--name", "tool", "--store", store,
        "-q")
    runs = json.loads(cli("runs", "--store", store, "--format", "json").stdout)
    assert sorted(r["name"] for r in runs) == ["tool[0]", "tool[1]"] and {r["plan"] for r in runs} == {"grid"}
    hit = cli("rcm-grid", *SMALL_OVERRIDES, "robot.tool_length_m=0.5", "--name", "short tool", "--store", store, "-q")
    assert "cache hit" in hit.stdout
    assert "short tool" in {r["name"] for r in json.loads(cli("runs", "--store", store, "--format", "json").stdout)}
    cli("rcm-grid", *SMALL_OVERRIDES, "robot.tool_length_m=0.5", "--tag", "surgeon=A", "--tag", "case=12", "--store",
        store, "-q")
    tagged = [r for r in json.loads(cli("runs", "--store", store, "--format", "json").stdout) if r["tags"]]
    assert [r["tags"] for r in tagged] == [{"surgeon": "A", "case": "12"}] and tagged[0]["name"] == "short tool"
    assert cli("rcm-grid", *SMALL_OVERRIDES, "--tag", "nokey", "--store", store, check=False).returncode == 2
    table = json.loads(cli("runs", "--store", store, "--compare", "--study", "rcm-grid", "--format", "json").stdout)
    assert [list(r["params"]) for r in table] == [["robot.tool_length_m"]] * 2  # only what differs
    assert sorted(r["params"]["robot.tool_length_m"] for r in table) == [0.5, 0.587]
    assert all("best_gii" in r["metrics"] for r in table)
    assert "robot.tool_length_m" in cli("runs", "--store", store, "--compare", "--study", "rcm-grid").stdout
    assert cli("runs", "--store", store, "--compare", check=False).returncode == 2  # needs --study


def test_print_config_round_trips_to_the_same_key(tmp_path):
    from surgopt.config import study_key

    r = cli("rcm-grid", *SMALL_OVERRIDES, "robot.elbow=down", "--print-config")
    (tmp_path / "printed.toml").write_text(r.stdout)
    printed = load_config(tmp_path / "printed.toml", S.Config)
    assert printed.robot.elbow == "down" and printed.workspace.points_per_side == 3
    stored = cli("rcm-grid", *SMALL_OVERRIDES, "robot.elbow=down", "--store", tmp_path / "s", "-q")
    assert "rcm-grid" in stored.stdout
    assert single_run(tmp_path / "s").key == study_key("rcm-grid", printed, S.KERNEL_VERSION)


def test_dry_run_says_what_would_run_and_writes_nothing(tmp_path):
    store = tmp_path / "store"
    r = cli("rcm-grid", *SMALL_OVERRIDES, "--dry-run", "--store", store)
    assert "20 RCM candidates" in r.stdout and "not stored" in r.stdout and "within budget" in r.stdout
    assert not store.exists()
    cli("rcm-grid", *SMALL_OVERRIDES, "--store", store, "-q")
    assert "stored (a cache hit)" in cli("rcm-grid", *SMALL_OVERRIDES, "--dry-run", "--store", store).stdout
    huge = cli("rcm-grid", "candidates.grid.x_count=2001", "candidates.grid.z_count=2001",
               "workspace.points_per_side=101", "--dry-run", "--store", store)
    assert "REFUSED" in huge.stdout


def test_export_diff_and_json_formats(tmp_path):
    import json

    import pandas as pd

    store = tmp_path / "store"
    cli("rcm-grid", *SMALL_OVERRIDES, "robot.tool_length_m=0.5,0.587", "-m", "--store", store, "-q")
    runs = json.loads(cli("runs", "--store", store, "--format", "json").stdout)
    assert [set(r) >= {"study", "key", "config_name", "rows", "state", "versions", "backend", "jobs", "host",
                       "wall_time_s"} for r in runs] == [True, True]
    a, b = (r["key"][:10] for r in runs)
    out = tmp_path / "both.csv"
    cli("export", a, b, "--store", store, "--out", out)
    df = pd.read_csv(out)
    assert len(df) == 40 and list(df.columns[:2]) == ["run_key", "robot.tool_length_m"]
    assert sorted(df["robot.tool_length_m"].unique()) == [0.5, 0.587]
    one = pd.read_csv(__import__("io").StringIO(cli("export", a, "--store", store).stdout))
    assert (one["run_key"] == runs[0]["key"]).all()
    pd.testing.assert_frame_equal(one.drop(columns="run_key"), Store(store).runs()[0].read_table(S.schema()).to_pandas(),
                                  check_dtype=False)
    cli("export", a, "--store", store, "--format", "parquet", "--out", tmp_path / "a.parquet")
    assert pd.read_parquet(tmp_path / "a.parquet").shape[0] == 20
    import duckdb

    assert duckdb.sql(f"SELECT count(DISTINCT run_key), count(*) FROM read_csv('{out}')").fetchall() == [(2, 40)]
    assert duckdb.sql(f"SELECT count(*) FROM '{tmp_path / 'a.parquet'}'").fetchall() == [(20,)]
    d = json.loads(cli("diff", a, b, "--store", store, "--format", "json").stdout)
    assert d["config"] == {"robot.tool_length_m": [0.5, 0.587]} or d["config"] == {"robot.tool_length_m": [0.587, 0.5]}
    assert d["rows_joined"] == 20 and "gii" in d["metrics"] and d["objective"] == "gii"
    table = cli("diff", a, b, "--store", store, env={**os.environ, "COLUMNS": "100"}).stdout
    assert "robot.tool_length_m" in table
    # floats to 6 significant digits in the tables (#27 item 10: they were folded mid-number)
    import re

    numbers = re.sub(r"\b[0-9a-f]{12}\b", "", table)  # the runs' 12-hex-digit keys (all digits 1 time in 280)
    assert not re.search(r"\d{9,}", numbers), table  # no 15-17 digit reprs
    s = json.loads(cli("summarize", a, "--store", store, "--format", "json").stdout)
    assert set(s) >= {"study", "key", "rows", "complete", "feasibility", "headline", "objective", "top", "distribution"}
    assert s["headline"]["best_gii"] == max(t["gii"] for t in s["top"])  # full precision, not rounded
    assert set(s["distribution"]["all"]) == {"count", "min", "p25", "median", "p75", "max", "mean"}


def test_version_completion_and_choices():
    from surgopt import __version__

    assert cli("--version").stdout.strip() == f"surgopt {__version__}"
    # the completion script, asked for the way the installed completion asks (`--show-completion` detects the
    # shell from the process tree, which a test run in the background does not have)
    import os

    assert "_surgopt_completion" in cli(env={**os.environ, "_SURGOPT_COMPLETE": "source_bash"}).stdout
    r = cli("rcm-grid", "--backend", "nosuch", check=False)
    assert r.returncode == 2 and "threads" in r.stderr and "loky" in r.stderr
    helps = cli("rcm-grid", "--help").stdout
    assert "[default: ./surgopt-store]" in " ".join(helps.split()) or "./surgopt-store" in helps


def test_every_readme_command_line_is_valid_as_written(tmp_path, monkeypatch):
    """#27 ("the README's examples all run as written"): every `surgopt ...` line of the README's bash blocks.
    A study command runs with --dry-run added (its config, overrides and flags validated, nothing computed; a
    placeholder file such as my_arm.urdf or a remote scheduler is left out); any other command must accept
    every option the line gives (its --help lists them)."""
    import re
    import shlex

    from conftest import REPO, invoke

    from surgopt.studies import STUDIES

    monkeypatch.chdir(REPO)  # the README's paths are the repository's
    monkeypatch.setenv("COLUMNS", "250")
    readme = (REPO / "README.md").read_text()
    lines = [ln.split(" #")[0].split(" > ")[0].strip() for b in re.findall(r"```bash\n(.*?)```", readme, re.S)
             for ln in b.splitlines()]
    lines = [ln[ln.index("surgopt "):] for ln in lines if "surgopt " in ln]
    studies, others = 0, 0
    for line in lines:
        args = shlex.split(line)[1:]
        if not args or args[0].startswith("-"):
            continue
        if args[0] in STUDIES:
            if "my_arm.urdf" in args or "my.yaml" in args or "--scheduler" in args or "--help" in args:
                continue
            if "--store" in args:
                i = args.index("--store")
                del args[i:i + 2]
            code, out = invoke(*args, "--dry-run", "--store", tmp_path / "store")
            assert code == 0, (line, out[-500:])
            studies += 1
        else:
            sub = [args[0]] + (["rm"] if args[1:2] == ["rm"] else [])
            code, shown = invoke(*sub, "--help")
            for opt in (a for a in args if a.startswith("--")):
                assert opt in shown, (line, opt)
            others += 1
    assert studies >= 20 and others >= 10  # the premise: the README's lines were found
    assert not (tmp_path / "store").exists()  # nothing written


def test_another_studys_flag_is_named_as_such(tmp_path):
    """#42 item 11: `port-place --robot ur5e` suggested --jobs, --verbose; it now says whose flag --robot is and
    where port-place takes its arms from (exit 2, nothing written); a mistyped shared option keeps click's
    suggestion."""
    r = cli("port-place", "--robot", "ur5e", "--store", tmp_path / "s", check=False)
    assert r.returncode == 2 and "--robot is a flag of rcm-grid" in r.stderr and "--verbose" not in r.stderr
    assert not (tmp_path / "s").exists()
    r = cli("port-place", "--jbs", "2", "--store", tmp_path / "s", check=False)
    assert r.returncode == 2 and "--jobs" in r.stderr


def test_help_keeps_every_bracket_it_is_given():
    """#56 item 7: Rich read "[default: ...]" in an option's help as markup and dropped it ("Output file .",
    "exceeds this ."). No command's help (the study commands' too) holds a "[" that is not escaped, and the
    rendered --help shows each default."""
    import re

    import typer.main
    from typer.testing import CliRunner

    from surgopt.cli import app

    group = typer.main.get_command(app)
    seen = []
    for name in group.list_commands(None):
        command = group.get_command(None, name)
        for p in command.params:
            assert not re.search(r"(?<!\\)\[", getattr(p, "help", None) or ""), (name, p.name, p.help)
            seen.append(p.name)
    assert "max_memory_gb" in seen and "out" in seen  # the premise: the study commands' options were walked
    for args, shown in ((["export", "--help"], "[default: standard output"),
                        (["port-place", "--help"], "[default: half of this machine"),
                        (["report", "--help"], "[default: beside the run")):
        out = CliRunner().invoke(app, args, env={"COLUMNS": "200"}).output
        assert shown in " ".join(out.replace("│", " ").split()), (args, out)
    lead = CliRunner().invoke(app, ["port-place", "--help"], env={"COLUMNS": "100"}).output.splitlines()[:16]
    assert sum(line.strip().startswith("Example: surgopt port-place") for line in lead) == 2  # leads with two
    assert any(line.strip().startswith("Frame: the patient's, in mm") for line in lead)


def test_a_mistyped_study_is_suggested_like_any_command():
    """#56 item 10: 'surgopt port-placee' had no "Did you mean" (Typer looks only at the commands built, and a
    study's is built when it is run); 'reportt' had one."""
    from typer.testing import CliRunner

    from surgopt.cli import app

    for typo, meant in (("port-placee", "'port-place'"), ("rcm-gird", "'rcm-grid'"), ("reportt", "'report'")):
        out = CliRunner().invoke(app, [typo]).output
        assert f"No such command '{typo}'. Did you mean {meant}" in " ".join(out.replace("│", " ").split()), out


def test_a_long_phase_says_what_it_does_and_a_quick_or_quiet_one_says_nothing(monkeypatch):
    """#56 item 5: the closing report of a large run and the page of `surgopt report` were minutes of silence. A
    phase under ``announced`` says what it does with the time so far once it has taken ANNOUNCE_AFTER_S, then every
    ANNOUNCE_EVERY_S; a phase that ends first, or --quiet, says nothing (the delays shortened for the test; the
    thread's lines are counted, not timed)."""
    import threading

    from surgopt import cli_common

    monkeypatch.setattr(cli_common, "ANNOUNCE_AFTER_S", 0.05)
    monkeypatch.setattr(cli_common, "ANNOUNCE_EVERY_S", 0.05)
    said, spoke = [], threading.Event()
    with cli_common.announced("building the page", say=lambda m: (said.append(m), spoke.set())):
        assert spoke.wait(30)  # the phase lasts until the announcement has come
    assert said and said[0].startswith("building the page ... (") and said[0].endswith(" s)")
    quick, quiet = [], []
    monkeypatch.setattr(cli_common, "ANNOUNCE_AFTER_S", 60.0)
    with cli_common.announced("quick", say=quick.append):
        pass
    with cli_common.announced("quiet", say=quiet.append, quiet=True):
        pass
    assert quick == [] and quiet == []


def test_runs_compare_shows_the_headline_first_and_paths_and_hashes_short():
    """#56 items 8 and 10: ``runs --compare`` put the differing config values before the headline (a narrow
    terminal kept a landmark's coordinates and dropped best_cost) and printed a mesh's absolute path and its
    64-hex hash whole. The text table shows a path by its file name and a hash by 12 digits; JSON keeps them."""
    from surgopt.cli_results import _short

    assert _short("/home/me/patients/openhelp/wall.stl") == "wall.stl"
    assert _short("ab" * 32) == "ab" * 6
    assert _short([1.0, 2.0]) == "[1.0, 2.0]" and _short("dome") == '"dome"'


def test_runs_compare_puts_the_headline_before_the_config_values(tmp_path):
    from pathlib import Path

    from conftest import invoke

    base = Path(__file__).parent / "baselines" / "rcm_small.toml"
    for length in ("0.2", "0.25"):
        assert invoke("rcm-grid", base, f"robot.tool_length_m={length}", "--store", tmp_path, "--quiet")[0] == 0
    code, out = invoke("runs", "--store", tmp_path, "--compare", "--study", "rcm-grid")
    header = next(line for line in out.splitlines() if "key" in line and "plan" in line)
    assert code == 0 and header.index("best_gii") < header.index("robot.tool_length_m"), header


def test_a_piped_table_honours_the_columns_a_user_set(tmp_path):
    """#56 item 8: in a pipe COLUMNS was ignored (400-730-character lines). Piped with COLUMNS=80, summarize's tables
    fit 80 characters and say which columns they left out; without COLUMNS a pipe still gets every column."""
    from pathlib import Path

    from typer.testing import CliRunner

    from surgopt.cli import app

    base = Path(__file__).parent / "baselines" / "port_small.toml"
    runner = CliRunner()
    assert runner.invoke(app, ["port-place", str(base), "--store", str(tmp_path), "--quiet"]).exit_code == 0
    narrow = runner.invoke(app, ["summarize", "latest", "--store", str(tmp_path)], env={"COLUMNS": "80"}).output
    wide = runner.invoke(app, ["summarize", "latest", "--store", str(tmp_path)], env={"COLUMNS": None}).output
    assert max(map(len, narrow.splitlines())) <= 80 and "not shown at 80 columns" in narrow
    assert max(map(len, wide.splitlines())) > 80 and "not shown" not in wide


def test_a_study_command_prints_its_closing_report_as_json_markdown_or_csv(tmp_path):
    """#56 item 8: a study command takes ``--format`` (table, markdown, csv, json): the closing report on standard
    output alone (the progress and the cache hit on standard error), its headline the run's recorded one, and the
    same numbers in every format; the table format is the terminal's as before."""
    import csv
    import io
    import json

    import pytest

    from conftest import RCM_SMALL
    from surgopt.store import Store

    cfg = tmp_path / "c.toml"
    cfg.write_text(RCM_SMALL)
    first = cli("rcm-grid", cfg, "--store", tmp_path / "s", "--format", "json", cwd=tmp_path)
    doc = json.loads(first.stdout)  # nothing else on standard output
    assert doc["study"] == "rcm-grid" and "chunks" in first.stderr  # the progress bar went to standard error
    (run,) = Store(tmp_path / "s").runs("rcm-grid")
    recorded = run.manifest["headline"]
    assert doc["run_key"] == run.key
    for k, v in recorded.items():
        assert doc["headline"][k] == (pytest.approx(v) if isinstance(v, float) else v), k
    assert doc["tables"] and all(isinstance(rows, list) for rows in doc["tables"].values())
    again = cli("rcm-grid", cfg, "--store", tmp_path / "s", "--format", "csv", cwd=tmp_path)
    assert "cache hit" in again.stderr and "cache hit" not in again.stdout
    head = again.stdout.split("\n# ")[0].splitlines()
    assert head[0].startswith("# rcm-grid")
    values = {r["field"]: r["value"] for r in csv.DictReader(io.StringIO("\n".join(head[1:])))}
    assert float(values["feasible"]) == recorded["feasible"]
    md = cli("rcm-grid", cfg, "--store", tmp_path / "s", "--format", "markdown", cwd=tmp_path).stdout
    assert md.startswith("### rcm-grid") and f"| feasible | {recorded['feasible']} |" in md
    bad = cli("rcm-grid", cfg, "--store", tmp_path / "s", "--format", "yaml", check=False, cwd=tmp_path)
    assert bad.returncode == 2 and "yaml" in bad.stderr


def test_diff_and_runs_print_their_tables_as_csv_or_markdown(tmp_path):
    """#56 item 8: every command that prints a table takes --format table|csv|json|markdown; diff and runs took
    table or json only. CSV: each table under a '# title' line, the same numbers as the table and the JSON; words
    between the tables go to standard error, so the pipe reads tables alone."""
    import csv
    import io
    import json

    from typer.testing import CliRunner

    from conftest import RCM_SMALL
    from surgopt.cli import app

    cfg = tmp_path / "c.toml"
    cfg.write_text(RCM_SMALL)
    runner = CliRunner()
    store = str(tmp_path / "s")
    for extra in ([], ["candidates.grid.x_count=7"]):
        r = runner.invoke(app, ["rcm-grid", str(cfg), *extra, "--store", store, "--quiet"])
        assert r.exit_code == 0, r.output
    keys = [run["key"][:12] for run in json.loads(runner.invoke(app, ["runs", "--store", store, "--format", "json"]).stdout)]
    assert len(keys) == 2  # the premise: two runs that differ
    doc = json.loads(runner.invoke(app, ["diff", *keys, "--store", store, "--format", "json"]).stdout)
    text = runner.invoke(app, ["diff", *keys, "--store", store, "--format", "csv"]).stdout
    blocks = [b for b in text.split("# ") if b.strip()]
    assert blocks[0].startswith("config:")
    config = list(csv.DictReader(io.StringIO(blocks[0].split("\n", 1)[1])))
    assert {row["field"] for row in config} == set(doc["config"])
    md = runner.invoke(app, ["diff", *keys, "--store", store, "--format", "markdown"]).stdout
    assert md.startswith("### config:") and "| field | a | b |" in md
    listed = runner.invoke(app, ["runs", "--store", store, "--format", "csv"]).stdout
    rows = list(csv.DictReader(io.StringIO(listed.split("\n", 1)[1])))
    assert listed.startswith("# runs in") and sorted(r["key"] for r in rows) == sorted(keys)
    compared = runner.invoke(app, ["runs", "--compare", "--study", "rcm-grid", "--store", store, "--format",
                                   "markdown"]).stdout
    assert compared.startswith("### rcm-grid runs in") and all(k in compared for k in keys)
