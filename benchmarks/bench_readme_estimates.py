"""Every study line of the README's Usage block: what `--dry-run` estimates against what the run then takes.

Run:  python benchmarks/bench_readme_estimates.py [--cold]     (from the checkout; ~5 min on 2 cores)

Each line runs twice in a fresh store: with `--dry-run` (its "time on N core(s)" column: the estimate of the
computing, summed over the runs a line makes) and for real with `--force --quiet` (the `time_s` the run
reports, summed: warm-up, computing and storing; the process start is not in either). The kernels are
compiled first (`surgopt warm`), so the times are warm; the first-run compile is its own line, per study,
from `surgopt warm` on an empty cache with `--cold` (the estimate does not include it, and the README says
so). A ratio measured/estimated above 2 or below 0.5 is flagged. Lines naming files that are not shipped
(my_arm.urdf, my.yaml) are skipped.
"""
from __future__ import annotations

import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
STUDIES = ("rcm-grid", "rcm-track", "raven-sweep", "suture-sim", "port-place")


def usage_lines() -> list[list[str]]:
    text = (REPO / "README.md").read_text()
    block = text[text.index("## Usage"):text.index("Options shared")]
    out = []
    for line in block.splitlines():
        words = line.split("#")[0].split()
        if len(words) >= 2 and words[0] == "surgopt" and words[1] in STUDIES and "--help" not in words:
            if any(w.endswith((".urdf", ".yaml")) and not (REPO / w).exists() for w in words):
                continue
            out.append(words[1:])
    return out


def seconds(text: str) -> float:
    """"1.5 s", "40 s", "12 min", "8 h 35 min" -> seconds."""
    m = re.fullmatch(r"\s*([\d.,]+) s\s*", text)
    if m:
        return float(m.group(1).replace(",", ""))
    m = re.fullmatch(r"\s*([\d.,]+) min\s*", text)
    if m:
        return 60 * float(m.group(1).replace(",", ""))
    m = re.fullmatch(r"\s*(\d+) h (\d+) min\s*", text)
    if m:
        return 3600 * int(m.group(1)) + 60 * int(m.group(2))
    raise ValueError(text)


def surgopt(args, store) -> str:
    r = subprocess.run([sys.executable, "-m", "surgopt", *args, "--store", str(store)], capture_output=True,
                       text=True, cwd=REPO, env={"COLUMNS": "400", **__import__("os").environ})
    if r.returncode != 0:
        raise RuntimeError(f"surgopt {' '.join(args)}: exit {r.returncode}\n{r.stderr[-600:]}")
    return r.stdout


def estimated_s(args, store) -> float:
    out = surgopt([*args, "--dry-run"], store)
    header = next(line for line in out.splitlines() if "time on" in line)
    cells = [c.strip() for c in re.split(r"[┃│]", header)]
    col = next(i for i, c in enumerate(cells) if c.startswith("time on"))
    total = 0.0
    for line in out.splitlines():
        cells = [c.strip() for c in re.split(r"[│┃]", line)]
        if len(cells) > col and cells[col] and re.match(r"[\d.,]+ (s|min|h)", cells[col]):
            total += seconds(cells[col])
    return total


def measured_s(args, store) -> float:
    out = surgopt([*args, "--force", "--quiet"], store)
    return sum(float(v) for v in re.findall(r"time_s\s*│\s*([\d.]+)", out))


def main() -> None:
    if "--cold" in sys.argv:
        with tempfile.TemporaryDirectory() as cache:
            t0 = time.perf_counter()
            r = subprocess.run([sys.executable, "-m", "surgopt", "warm"], capture_output=True, text=True,
                               env={**__import__("os").environ, "NUMBA_CACHE_DIR": cache, "COLUMNS": "200"})
            print(r.stdout)
            print(f"first-run compile of every study, empty cache: {time.perf_counter() - t0:.0f} s\n")
    subprocess.run([sys.executable, "-m", "surgopt", "warm"], capture_output=True, check=True)
    print("| README line | estimated (s) | measured (s) | measured / estimated |")
    print("|---|---|---|---|")
    flagged = 0
    for args in usage_lines():
        with tempfile.TemporaryDirectory() as store:
            est = estimated_s(args, store)
            got = measured_s(args, store)
        ratio = got / est if est > 0 else float("inf")
        flag = "" if 0.5 <= ratio <= 2 else " **outside 2x**"
        flagged += bool(flag)
        print(f"| `surgopt {' '.join(args)}` | {est:.1f} | {got:.1f} | {ratio:.2f}{flag} |")
    print(f"\n{flagged} line(s) outside 2x")


if __name__ == "__main__":
    main()
