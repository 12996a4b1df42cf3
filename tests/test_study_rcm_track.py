"""Study rcm-track (surgopt/studies/rcm_track/study.py): Table I's error column, the calibration, the CLI."""
import signal
import subprocess
import sys

import numpy as np
import pytest

from surgopt.config import load_config, load_embedded
from surgopt.studies.rcm_grid import study as G
from surgopt.studies.rcm_track import study as S

from conftest import REPO, cli, single_run, single_table, slowed, wait_for_parts


@pytest.fixture(scope="module")
def table1():
    cfg = load_embedded(S.DEFAULT_CONFIG, S.Config)
    return cfg, S.compute_task(cfg, 15, 0)


def test_spelled_out_config_equals_the_embedded_default_and_rcm_grid_configs_are_accepted():
    assert load_config(REPO / "configs" / "rcm_track_table1.toml", S.Config) == load_embedded(S.DEFAULT_CONFIG, S.Config)
    t1 = load_config(REPO / "configs" / "rcm_table1.toml", S.Config)  # an rcm-grid config as it is
    assert G.candidate_count(t1) == 15 and t1.track.keep == []


def test_the_calibrated_gain_gives_the_papers_best_error(table1):
    cfg, rows = table1
    assert abs(rows["max_tip_error_mm"][7] - 5.1) < 0.01
    assert abs(S.calibrate_gain(cfg, 7, 5.1) - S.CALIBRATED_GAIN_PER_S) < 0.01


def test_table_I_error_column_aims(table1):
    """docs/reproduction.md: Spearman >= 0.6 against the paper's 15 errors and the three x = 0.260 m rows
    the three largest (the paper's first finding); the large-x rows better than their GII predicts."""
    _, rows = table1
    e = rows["max_tip_error_mm"]
    assert rows["feasible"].all()
    rho = S.rank_correlation(S.PAPER_MAX_ERROR_MM, e)
    assert rho >= 0.6
    assert set(np.argsort(-e)[:3]) == {12, 13, 14}
    # large-x candidates (x >= 0.65 m): GII ~0.011-0.015, as poor as the x = 0.26 rows', yet they track like
    # the best (within 30% of its error): the path moves them mostly in y
    large_x = rows["x_rcm_m"] >= 0.65
    assert (rows["gii"][large_x] < 0.016).all() and (e[large_x] < 1.3 * e[7]).all()
    assert (e[12:] > 3 * e[7]).all()


def test_the_tracking_magnitudes_are_not_reproduced_as_the_doc_says(table1):
    """docs/reproduction.md says plainly that the magnitudes are not reproduced: both directions held. The
    x = 0.26 m rows are about 5x the paper's (90 mm against 16-17 mm), (0.350, -0.210) about 3x (21 against
    6.3 mm); the unsaturated rows sit within 0.5 mm of the paper's, which the gain calibrated on row 7 makes
    close to automatic (their error is mostly the lag v / K)."""
    _, rows = table1
    e, paper = rows["max_tip_error_mm"], np.asarray(S.PAPER_MAX_ERROR_MM)
    ratio = e / paper
    assert (ratio[12:] > 4.5).all() and (ratio[12:] < 6.0).all()
    assert 3.0 < ratio[9] < 4.0  # (0.350, -0.210)
    unsaturated = rows["saturated_s"] < 0.3  # (0.400, -0.110) saturates for 0.24 s at no visible cost
    assert unsaturated.sum() == 11 and (np.abs(e - paper)[unsaturated] < 0.5).all()
    lag = 54.6 / S.CALIBRATED_GAIN_PER_S  # mm: the tip speed's lag under the calibrated gain
    assert (np.abs(e[unsaturated] - lag) < 1.5).all()


def test_the_ik_every_tenth_step_costs_microns(table1):
    cfg, rows = table1
    fine = cfg.model_copy(update={"candidates": G.Candidates(z_reference="shoulder", list_m=[[0.535, -0.21], [0.26, -0.14]]),
                                  "track": cfg.track.model_copy(update={"ik_every_steps": 1, "keep": []})})
    r = S.compute_task(fine, 2, 0)
    assert abs(r["max_tip_error_mm"][0] - rows["max_tip_error_mm"][7]) < 0.01
    assert abs(r["max_tip_error_mm"][1] - rows["max_tip_error_mm"][12]) < 0.1


def test_traces_only_for_kept_candidates(table1):
    _, rows = table1
    lens = [len(t) for t in rows["trace_t_s"]]
    assert lens[7] == 1001 and lens[12] == 1001 and sum(lens) == 2002
    assert abs(max(rows["trace_tip_error_mm"][7]) - rows["max_tip_error_mm"][7]) < 0.05


def test_unreachable_candidate_is_infeasible_with_nan_errors():
    cfg = load_embedded(S.DEFAULT_CONFIG, S.Config)
    cfg = cfg.model_copy(update={"candidates": G.Candidates(z_reference="shoulder", list_m=[[1.5, 0.0]]),
                                 "track": cfg.track.model_copy(update={"keep": []})})
    r = S.compute_task(cfg, 1, 0)
    assert not r["feasible"][0] and np.isnan(r["max_tip_error_mm"][0]) and r["gii"][0] == 0


def test_cli_cache_hit_bad_input_and_resume(tmp_path):
    store = tmp_path / "store"
    first = cli("rcm-track", "--store", store, "--quiet")
    assert "spearman_vs_paper" in first.stdout
    again = cli("rcm-track", "--store", store, "--quiet")
    assert "cache hit" in (again.stdout + again.stderr).lower()
    (tmp_path / "bad.toml").write_text("[track]\nkeep = [99999]\n")
    bad = cli("rcm-track", tmp_path / "bad.toml", "--store", tmp_path / "none", check=False)
    assert bad.returncode == 2 and "candidate_id 99999" in bad.stderr and not (tmp_path / "none").exists()
    # resume: a grid of 40 candidates, one per task, killed while its third task spins (tests/slow_cli.py): a
    # plain run's 20 ms tasks let a fast CI machine finish all 40 between two polls of the manifest
    slow = tmp_path / "slow.toml"
    slow.write_text("[candidates.grid]\nx_min_m = 0.45\nx_max_m = 0.6\nx_count = 8\nz_min_m = -0.4\nz_max_m = -0.1\n"
                    "z_count = 5\n[track]\nduration_s = 20.0\n")
    s2 = tmp_path / "s2"
    proc = subprocess.Popen(slowed("rcm-track", slow, "--store", s2, "--quiet", "--jobs", "1", "--chunk-size", "1"),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    wait_for_parts(s2, "rcm-track", 2, proc)
    proc.send_signal(signal.SIGKILL)
    proc.communicate(timeout=60)
    run = single_run(s2)
    done = len(run.manifest["parts"])
    assert not run.complete and done == 2
    r = cli("rcm-track", slow, "--store", s2, "--quiet")
    assert f"resuming: {done} of 40 chunks already stored" in r.stdout
    fresh = tmp_path / "fresh"
    cli("rcm-track", slow, "--store", fresh, "--quiet", "--chunk-size", "7")
    import pandas as pd

    # NaN (the infeasible candidates' errors) equals NaN here; Table.equals would say they differ
    pd.testing.assert_frame_equal(single_table(s2).to_pandas(), single_table(fresh).to_pandas(), check_exact=True)


def test_plot_writes_figs_4_5_and_6(tmp_path):
    store = tmp_path / "store"
    cli("rcm-track", "--store", store, "--quiet")
    r = cli("plot", "--store", store, "--study", "rcm-track", "--out", tmp_path / "figs")
    names = sorted(p.name for p in (tmp_path / "figs").iterdir())
    assert names == ["rcm_track_candidate_12.png", "rcm_track_candidate_7.png", "rcm_track_max_error.png"], r.stdout


def test_a_config_file_is_rcm_tracks_only_with_a_track_section():
    from surgopt.results import study_of_config

    assert study_of_config(REPO / "configs" / "rcm_table1.toml", None)[0].name == "rcm-grid"
    assert study_of_config(REPO / "configs" / "rcm_track_table1.toml", None)[0].name == "rcm-track"
    r = cli("rcm-grid", REPO / "configs" / "rcm_track_table1.toml", "--dry-run", check=False)
    assert r.returncode == 2 and "rcm-track config" in r.stderr
