"""kill -9 trials for docs/reliability.md: interrupt a run at a random chunk, resume, compare.

Run:  python docs/reliability_trials.py [N]   (N trials per backend, default 8; ~4 min for 8)

Starts `surgopt rcm-grid` on tests/conftest.py's RCM_SLOW config (4,961 candidates in 124 chunks of
40), waits until a random number (1-100) of parts is stored, sends SIGKILL, resumes with the same
command, and compares the table with an uninterrupted run, counting rows lost or duplicated.
Prints one Markdown row per backend.
"""
from __future__ import annotations

import glob
import json
import random
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from surgopt.store import Store  # noqa: E402

from conftest import RCM_SLOW  # noqa: E402


def table(store):
    (run,) = Store(store).runs()
    return run.read_table()


def surgopt(*args, **kw):
    return subprocess.run([sys.executable, "-m", "surgopt", "rcm-grid", *map(str, args), "-q"], check=True,
                          capture_output=True, **kw)


def main(n: int) -> None:
    tmp = Path(tempfile.mkdtemp())
    cfg = tmp / "slow.toml"
    cfg.write_text(RCM_SLOW)
    surgopt(cfg, "--store", tmp / "ref", "--chunk-size", "40")
    ref = table(tmp / "ref")
    rng = random.Random(1)
    print("| backend | trials | identical | rows lost | rows duplicated | killed after (parts) |")
    print("|---|---|---|---|---|---|")
    for backend in ("threads", "loky", "dask"):
        same = lost = dup = 0
        at = []
        for trial in range(n):
            store = tmp / f"{backend}-{trial}"
            p = subprocess.Popen([sys.executable, "-m", "surgopt", "rcm-grid", str(cfg), "--store", str(store), "-q",
                                  "--chunk-size", "40", "--backend", backend],
                                 stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            target = rng.randint(1, 100)
            while p.poll() is None:
                m = glob.glob(f"{store}/study=rcm-grid/key=*/_manifest.json")
                try:
                    if m and len(json.load(open(m[0]))["parts"]) >= target:
                        break
                except (OSError, ValueError):
                    pass
                time.sleep(0.005)
            p.kill()
            p.wait()
            done = len(Store(store).runs()[0].manifest["parts"]) if Store(store).runs() else 0
            at.append(done)
            surgopt(cfg, "--store", store, "--backend", backend)
            t = table(store)
            same += t.equals(ref)
            lost += max(0, ref.num_rows - t.num_rows)
            dup += max(0, t.num_rows - ref.num_rows)
            shutil.rmtree(store)
        print(f"| {backend} | {n} | {same} | {lost} | {dup} | {min(at)}-{max(at)} of 124 |", flush=True)
    shutil.rmtree(tmp)


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 8)
