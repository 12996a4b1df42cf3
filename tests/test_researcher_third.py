"""A researcher's third week (issue 42), the items done so far: tables that fit a terminal without cutting a number,
`plot` naming the run it drew, runs found by name and by `latest`."""
from __future__ import annotations

import io
import re

from conftest import RCM_SMALL, cli


def _table(width: int, terminal: bool) -> list[str]:
    from rich.console import Console

    from surgopt.cli_common import print_table

    out = io.StringIO()
    console = Console(file=out, width=width, force_terminal=terminal, color_system=None)
    header = ["design_id", *[f"a_long_column_name_{i}_mm" for i in range(10)]]
    rows = [[str(1_000_000 + r), *[f"{0.123456789 * (r + 1) * (i + 1):.6f}" for i in range(10)]] for r in range(5)]
    print_table(console, "top layouts", header, rows)
    return out.getvalue().splitlines()


def test_a_wide_table_fits_an_80_column_terminal_and_says_what_it_left_out():
    lines = _table(80, terminal=True)
    assert max(len(line) for line in lines) <= 80
    text = "\n".join(lines)
    assert "1000004" in text and "0.123457" in text  # numbers whole, never folded
    assert re.search(r"\d+ more column\(s\) not shown at 80 columns: .*a_long_column_name_9_mm", text, re.S)


def test_a_column_of_words_wraps_at_80_columns_instead_of_being_left_out():
    """#56 item 8: the closing report's clinical checks at 80 columns dropped the clinical number beside each check
    (a column of words); it now wraps, while the numbers beside it stay whole."""
    from rich.console import Console

    from surgopt.cli_common import print_table, words_column

    out = io.StringIO()
    header = ["quantity", "value", "clinical number", "within"]
    rows = [["instrument port to target centre, 3-D (mm)", "172.123",
             "80-180 (constraints.port_to_target_mm; <= 180: J Endourol 2004, port to pubis)", "yes"],
            ["manipulation angle over the target (deg)", "37.3 - 69.3", "45-75", "OUTSIDE"]]
    assert words_column([r[2] for r in rows]) and not words_column([r[1] for r in rows])  # the premise
    assert not words_column([r[3] for r in rows])
    print_table(Console(file=out, width=80, force_terminal=True, color_system=None), "clinical checks", header, rows)
    text = out.getvalue()
    assert max(map(len, text.splitlines())) <= 80 and "not shown" not in text
    assert "clinical number" in text and "Endourol" in text and "172.123" in text and "37.3 - 69.3" in text


def test_a_wide_table_to_a_pipe_keeps_every_column_whole():
    text = "\n".join(_table(80, terminal=False))
    assert "a_long_column_name_9_mm" in text and "not shown" not in text
    assert "1.234568" in text  # the last column's last number (0.123456789 * 5 * 10)


def test_plot_names_the_run_it_drew_and_runs_are_found_by_name_and_latest(tmp_path):
    cfg = tmp_path / "small.toml"
    cfg.write_text(RCM_SMALL)
    store = tmp_path / "s"
    cli("rcm-grid", cfg, "--store", store, "--quiet", "--name", "baseline-map")
    r = cli("plot", "--store", store, "--out", tmp_path / "figs")
    assert re.search(r"drew rcm-grid run [0-9a-f]{12} \(baseline-map, the latest run in the store\)", r.stderr)
    from conftest import single_run

    key = single_run(store).key[:12]
    assert key in cli("summarize", "baseline-map", "--store", store).stdout
    assert key in cli("summarize", "latest", "--store", store).stdout


def _urdf_with_leaves(tmp_path, leaves) -> str:
    """tests/data/pa10_7c.urdf with extra fixed leaf links on the flange (as ROS-Industrial URDFs have)."""
    from conftest import HERE

    text = (HERE / "data" / "pa10_7c.urdf").read_text()
    extra = "".join(f'<link name="{n}"/><joint name="{n}_joint" type="fixed"><parent link="flange"/>'
                    f'<child link="{n}"/><origin xyz="0 0 0" rpy="0 0 0"/></joint>' for n in leaves)
    path = tmp_path / "arm.urdf"
    path.write_text(text.replace("</robot>", extra + "</robot>"))
    return str(path)


def test_a_urdf_of_several_leaves_ends_at_tool0_and_says_so(tmp_path):
    """example-robot-data's ur5_robot.urdf (leaves base, ee_link, tool0) was refused with 'name one': tool0, the
    ROS-Industrial tool frame, is taken and the run says so; without a tool0 the refusal stands."""
    from conftest import invoke

    path = _urdf_with_leaves(tmp_path, ["ee_link", "tool0"])
    code, out = invoke("rcm-grid", "--robot", path, "robot.tool_length_m=0.3", "--dry-run", "--store",
                       str(tmp_path / "s"))
    assert code == 0, out
    assert "robot.tip_link: tool0 (the ROS-Industrial tool frame)" in out and "ee_link" in out
    path = _urdf_with_leaves(tmp_path, ["ee_link", "camera"])
    code, out = invoke("rcm-grid", "--robot", path, "robot.tool_length_m=0.3", "--dry-run", "--store",
                       str(tmp_path / "s"))
    assert code == 2 and "leaf links" in out and "name one" in out, out


def test_a_port_place_search_is_drawn_on_the_cost_of_its_feasible_trials(tmp_path):
    """Issue 42 item 7: the convergence of a port-place search drew its penalised score (-500 to 0), so the best
    feasible cost was a flat line. The figure and the page draw the feasible trials' cost."""
    from conftest import HERE

    cfg = tmp_path / "search.toml"
    cfg.write_text((HERE / "baselines" / "port_small.toml").read_text()
                   + '\n[search]\nmethod = "cmaes"\ntrials = 64\nbatch = 32\nseed = 0\n')
    store = tmp_path / "s"
    cli("port-place", cfg, "--store", store, "--quiet")
    r = cli("plot", "--store", store, "--out", tmp_path / "figs")
    assert "search_convergence.png" in r.stdout
    cli("report", "--store", store, "--out", tmp_path / "page.html")
    text = (tmp_path / "page.html").read_text()
    assert "cost (minimize) of the feasible trials only, on its own scale" in text


def test_the_3d_layout_figure_gives_sites_and_target_points_each_their_own_colour_bar(tmp_path, monkeypatch):
    """Issue 42 item 7: the 3-D layout figure drew the sites' cost and the target points' isotropy on one colour
    bar's scale; now each has its own palette and colour bar, labelled."""
    import numpy as np

    from surgopt.config import validate
    from surgopt.studies.port_place import config as C
    from surgopt.studies.port_place import figures as F
    from surgopt.studies.port_place import study as S

    labels = {}

    def kept(fig, path):
        labels[path.name] = sorted(a.get_ylabel() for a in fig.axes if a.get_label() == "<colorbar>")
        return path

    monkeypatch.setattr(F, "save", kept)
    cfg = validate({"patient": {"port_region": {"site_spacing_mm": 54.0}}, "target": {"spacing_mm": 20.0},
                    "cart": {"model": "none"}}, C.PortPlaceConfig, "x")
    rows = S.compute_task(cfg, 10 ** 6, 0)
    import pyarrow as pa

    F.figures(cfg, pa.table({k: np.asarray(v) for k, v in rows.items()}), tmp_path)
    assert labels["port_place_layout_3d.png"] == ["least cost of a feasible design using the site",
                                                  "target point: the instruments' smaller isotropy"]
