"""Random-interruption series for docs/reliability.md: a study and a search stopped at a random instant on
each backend by a random signal, resumed, and compared with an uninterrupted run.

Run:  python docs/interrupt_trials.py [N]   (N trials per backend and kind, default 20; ~20 min for 20)

Each trial starts `surgopt rcm-grid` (the study: tests/conftest.py's RCM_SLOW, 4,961 candidates in 124 chunks;
the search: a 400-trial TPE search in batches of 20), waits a random time drawn uniformly from 0 to the
uninterrupted run's own duration (so any instant: start-up, compiling, computing, storing, the closing
report), sends SIGKILL, SIGINT or SIGTERM (drawn at random; seeded), then resumes with the same command and
compares the table with the uninterrupted one. An interrupted command must end with its signal's exit code
(-9; 130; 143) and at most one line on stderr without a traceback; a command that finished before the signal
counts as finished. Prints one Markdown row per backend and kind.
"""
from __future__ import annotations

import random
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))

from surgopt.store import Store  # noqa: E402

from conftest import RCM_SLOW  # noqa: E402

SEARCH = """
[workspace]
points_per_side = 9
[search]
method = "tpe"
trials = 400
batch = 20
seed = 5
"""
EXIT = {signal.SIGKILL: -9, signal.SIGINT: 130, signal.SIGTERM: 143}


def table(store):
    (run,) = Store(store).runs()
    return run.read_table()


def command(cfg, store, backend):
    return [sys.executable, "-m", "surgopt", "rcm-grid", str(cfg), "--store", str(store), "-q", "--backend", backend]


def series(cfg, tmp: Path, kind: str, backend: str, n: int, rng: random.Random) -> dict:
    t0 = time.perf_counter()
    subprocess.run(command(cfg, tmp / f"ref-{kind}-{backend}", backend), check=True, capture_output=True)
    duration = time.perf_counter() - t0
    ref = table(tmp / f"ref-{kind}-{backend}")
    out = {"trials": n, "interrupted": 0, "finished first": 0, "clean stop": 0, "identical": 0, "bad": []}
    for trial in range(n):
        store = tmp / f"{kind}-{backend}-{trial}"
        sig = rng.choice(list(EXIT))
        delay = rng.uniform(0, duration)
        p = subprocess.Popen(command(cfg, store, backend), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                             text=True)
        time.sleep(delay)
        finished = p.poll() is not None
        if not finished:
            p.send_signal(sig)
        err = p.communicate()[1]
        if finished or p.returncode == 0:
            out["finished first"] += 1
        else:
            out["interrupted"] += 1
            lines = err.strip().splitlines()
            # SIGKILL: nothing of ours can speak; a helper (the resource tracker) may note leaked semaphores
            if p.returncode == EXIT[sig] and (sig == signal.SIGKILL or (len(lines) <= 1 and "Traceback" not in err)):
                out["clean stop"] += 1
            else:
                out["bad"].append(f"{sig.name} at {delay:.2f} s: exit {p.returncode}, {len(lines)} lines: "
                                  f"{err.strip()[:200]!r}")
        r = subprocess.run(command(cfg, store, backend), capture_output=True, text=True)
        if r.returncode == 0 and table(store).equals(ref):
            out["identical"] += 1
        else:
            out["bad"].append(f"resume after {sig.name} at {delay:.2f} s: exit {r.returncode} {r.stderr.strip()[:200]!r}")
    out["duration_s"] = duration
    return out


def main(n: int) -> None:
    tmp = Path(tempfile.mkdtemp())
    cfgs = {"study": tmp / "study.toml", "search": tmp / "search.toml"}
    cfgs["study"].write_text(RCM_SLOW)
    cfgs["search"].write_text(SEARCH)
    rng = random.Random(2026)
    print("| kind | backend | trials | interrupted | finished first | one line, right exit code | "
          "resumed identical | uninterrupted run (s) |")
    print("|---|---|---|---|---|---|---|---|")
    problems = []
    for kind, cfg in cfgs.items():
        for backend in ("threads", "loky", "dask"):
            r = series(cfg, tmp, kind, backend, n, rng)
            print(f"| {kind} | {backend} | {r['trials']} | {r['interrupted']} | {r['finished first']} | "
                  f"{r['clean stop']}/{r['interrupted']} | {r['identical']}/{r['trials']} | {r['duration_s']:.1f} |",
                  flush=True)
            problems += [f"{kind}/{backend}: {b}" for b in r["bad"]]
    for b in problems:
        print("-", b)


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 20)
