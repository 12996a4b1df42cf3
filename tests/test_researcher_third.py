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
