"""`surgopt report` after every study line of the README's Usage block (issue 41's "done means"): each line runs in a
store of its own, then its latest run's page is built and opened in headless Chromium: no console error, no
request, every figure drawn. Prints one Markdown row per line: the page's size, build time and figures.

Run:  python benchmarks/readme_reports.py        (~6 min on 2 cores: it runs every README line, metric=standard too)
"""
from __future__ import annotations

import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))

from bench_readme_estimates import REPO, usage_lines  # noqa: E402


def main() -> None:
    from playwright.sync_api import sync_playwright

    print("| README line | page (MB) | built (s) | figures drawn | console errors | requests |")
    print("|---|---|---|---|---|---|")
    bad = 0
    with sync_playwright() as p, tempfile.TemporaryDirectory() as tmp:
        browser = p.chromium.launch(executable_path=shutil.which("chromium"),
                                    args=["--enable-unsafe-swiftshader", "--no-sandbox"])
        for n, args in enumerate(usage_lines()):
            store = Path(tmp) / f"s{n}"
            subprocess.run([sys.executable, "-m", "surgopt", *args, "--store", str(store), "--quiet"], check=True,
                           capture_output=True, cwd=REPO)
            page = Path(tmp) / f"p{n}.html"
            t0 = time.perf_counter()
            subprocess.run([sys.executable, "-m", "surgopt", "report", "--store", str(store), "--out", str(page)],
                           check=True, capture_output=True, cwd=REPO)
            built = time.perf_counter() - t0
            tab = browser.new_page(viewport={"width": 1400, "height": 1000})
            errors, requests = [], []
            tab.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
            tab.on("pageerror", lambda e: errors.append(str(e)))
            tab.on("request", lambda r: requests.append(r.url) if not r.url.startswith(("file:", "data:")) else None)
            tab.goto(page.as_uri())
            tab.wait_for_selector("body[data-ready]", timeout=300_000)
            tab.evaluate("drawAllPlots()")
            tab.wait_for_selector("body[data-all]", state="attached", timeout=300_000)
            figures = tab.locator(".js-plotly-plot").count()
            tab.close()
            bad += bool(errors or requests or not figures)
            print(f"| `surgopt {' '.join(args)}` | {page.stat().st_size / 2 ** 20:.1f} | {built:.1f} | {figures} | "
                  f"{len(errors)} | {len(requests)} |", flush=True)
        browser.close()
    print(f"\n{bad} page(s) with an error, a request or no figure")


if __name__ == "__main__":
    main()
