"""The README's screenshot of the port-place page (docs/figures/report_port_place.png): the embedded default run's
`surgopt report` opened in headless Chromium (Debian's), scrolled to the layout on the patient once drawn.

Run:  python docs/screenshot_report.py [STORE]   (default: a temporary store; the run is computed first, ~15 s)
"""
from __future__ import annotations

import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

OUT = Path(__file__).parent / "figures" / "report_port_place.png"


def main(store: Path) -> None:
    subprocess.run([sys.executable, "-m", "surgopt", "port-place", "--store", str(store), "--quiet"], check=True,
                   stdout=subprocess.DEVNULL)
    page = store / "report.html"
    subprocess.run([sys.executable, "-m", "surgopt", "report", "--store", str(store), "--study", "port-place",
                    "--out", str(page)], check=True, stdout=subprocess.DEVNULL)
    from playwright.sync_api import sync_playwright

    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=shutil.which("chromium"),
                                    args=["--enable-unsafe-swiftshader", "--no-sandbox"])
        tab = browser.new_page(viewport={"width": 1400, "height": 1000})
        tab.goto(page.as_uri())
        tab.wait_for_selector("body[data-ready]", state="attached", timeout=300_000)
        tab.evaluate("document.getElementById('pp-scene').closest('section').scrollIntoView()")  # the layout
        tab.wait_for_timeout(500)
        tab.screenshot(path=str(OUT))
        browser.close()
    print(OUT)


if __name__ == "__main__":
    if len(sys.argv) > 1:
        main(Path(sys.argv[1]))
    else:
        with tempfile.TemporaryDirectory() as d:
            main(Path(d) / "store")
