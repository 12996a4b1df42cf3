"""Random-interruption series for docs/reliability.md: a study and a search stopped at a random instant on
each backend by a random signal, resumed, and compared with an uninterrupted run.

Run:  python docs/interrupt_trials.py [N] [KIND ...]   (N trials per backend and kind, default 20; ~20 min for 20
      of the first two kinds; KIND: study, search, standard, branches, port-serial, group, ulimit; default all)

Each trial starts a command (the study: `surgopt rcm-grid` on tests/conftest.py's RCM_SLOW, 4,961 candidates in
124 chunks; the search: a 400-trial TPE search in batches of 20; standard: `metric=standard`, whose chunks are
long; branches: `--robot ur5e --branches`, one run per IK branch; port-serial: `surgopt port-place
configs/port_place_pa10.toml`, serial arms keeping the RCM in software; group: the signal sent to the whole process
group, as a terminal's Ctrl-C is; ulimit: under `ulimit -v` ULIMIT_MB), waits a random time drawn uniformly from 0 to the
uninterrupted run's own duration (so any instant: start-up, compiling, computing, storing, the closing
report), sends SIGKILL, SIGINT or SIGTERM (drawn at random; seeded), then resumes with the same command and
compares the tables with the uninterrupted ones. An interrupted command must end with its signal's exit code
(-9; 130; 143), within STOP_WITHIN_S of the signal, and at most one line on stderr without a traceback; a command
that finished before the signal counts as finished. Prints one Markdown row per backend and kind, with the
longest time from a signal to the end of the process.
"""
from __future__ import annotations

import os
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
STANDARD = """
metric = "standard"
[candidates.grid]
x_min_m = 0.3
x_max_m = 0.7
x_count = 21
z_min_m = -0.4
z_max_m = 0.0
z_count = 21
"""
BRANCHES = """
[candidates.grid]
x_min_m = 0.2
x_max_m = 0.6
x_count = 21
z_min_m = -0.2
z_max_m = 0.2
z_count = 21
"""
EXIT = {signal.SIGKILL: -9, signal.SIGINT: 130, signal.SIGTERM: 143}
#: The longest a stop may take from the signal to the end of the process (issue 38: 5 s).
STOP_WITHIN_S = 5.0
REPO = Path(__file__).resolve().parents[1]
#: kind -> (study, config text or a shipped config's path, extra arguments, backends)
KINDS = {
    "study": ("rcm-grid", RCM_SLOW, [], ("threads", "loky", "dask")),
    "search": ("rcm-grid", SEARCH, [], ("threads", "loky", "dask")),
    "standard": ("rcm-grid", STANDARD, [], ("threads", "loky")),
    "branches": ("rcm-grid", BRANCHES, ["--robot", "ur5e", "--branches"], ("threads",)),
    "port-serial": ("port-place", REPO / "configs" / "port_place_pa10.toml", [], ("threads",)),
    # the signal to the whole process group, as a terminal's Ctrl-C sends it: the workers must stay quiet
    "group": ("rcm-grid", RCM_SLOW, [], ("loky", "dask")),
    # under an address-space limit (ulimit -v) the run fits in
    "ulimit": ("rcm-grid", RCM_SLOW, [], ("threads", "loky")),
}
#: The address-space limit of the "ulimit" kind (MB): above the run's need (282 + 700 MB).
ULIMIT_MB = 1200


def _limit():
    import resource

    resource.setrlimit(resource.RLIMIT_AS, (ULIMIT_MB * 2 ** 20, ULIMIT_MB * 2 ** 20))


def popen_kw(kind) -> dict:
    return {"start_new_session": kind == "group", "preexec_fn": _limit if kind == "ulimit" else None}


def table(store):
    """Every run's table, by key (a --branches command stores one run per branch)."""
    return {run.key: run.read_table() for run in Store(store).runs()}


def same(a: dict, b: dict) -> bool:
    return a.keys() == b.keys() and all(a[k].equals(b[k]) for k in a)


def how_they_differ(a: dict, b: dict) -> str:
    """Where a resumed run's tables differ from the uninterrupted run's: keys, row counts, the columns and rows."""
    if a.keys() != b.keys():
        return f"; runs {sorted(k[:8] for k in a)} vs {sorted(k[:8] for k in b)}"
    out = []
    for k in a:
        x, y = a[k], b[k]
        if x.num_rows != y.num_rows:
            out.append(f"{k[:8]}: {x.num_rows} vs {y.num_rows} rows")
            continue
        for c in x.column_names:
            if not x[c].equals(y[c]):
                xs, ys = x[c].to_pylist(), y[c].to_pylist()
                rows = [i for i, (p, q) in enumerate(zip(xs, ys)) if p != q]
                out.append(f"{k[:8]}.{c}: {len(rows)} rows differ, e.g. row {rows[0]}: {xs[rows[0]]!r} vs "
                           f"{ys[rows[0]]!r}" if rows else f"{k[:8]}.{c}: equal values, unequal arrays")
    return "; " + "; ".join(out)


def command(kind, cfg, store, backend):
    study, _, extra, _ = KINDS[kind]
    return [sys.executable, "-m", "surgopt", study, str(cfg), *extra, "--store", str(store), "-q", "--backend", backend]


def series(cfg, tmp: Path, kind: str, backend: str, n: int, rng: random.Random) -> dict:
    t0 = time.perf_counter()
    subprocess.run(command(kind, cfg, tmp / f"ref-{kind}-{backend}", backend), check=True, capture_output=True,
                   **popen_kw(kind))
    duration = time.perf_counter() - t0
    ref = table(tmp / f"ref-{kind}-{backend}")
    out = {"trials": n, "interrupted": 0, "finished first": 0, "clean stop": 0, "identical": 0, "bad": [],
           "longest stop": 0.0}
    for trial in range(n):
        store = tmp / f"{kind}-{backend}-{trial}"
        sig = rng.choice(list(EXIT))
        delay = rng.uniform(0, duration)
        p = subprocess.Popen(command(kind, cfg, store, backend), stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                             text=True, **popen_kw(kind))
        time.sleep(delay)
        finished = p.poll() is not None
        t_signal = time.perf_counter()
        if not finished:
            if kind == "group":
                os.killpg(p.pid, sig)
            else:
                p.send_signal(sig)
        err = p.communicate()[1]
        took = time.perf_counter() - t_signal
        if not finished and p.returncode != 0:
            out["longest stop"] = max(out["longest stop"], took)
        if finished or p.returncode == 0:
            out["finished first"] += 1
        else:
            out["interrupted"] += 1
            lines = [ln for ln in err.strip().splitlines() if not ln.startswith("OpenBLAS")]
            # SIGKILL: nothing of ours can speak; a helper (the resource tracker) may note leaked semaphores
            if p.returncode == EXIT[sig] and took <= STOP_WITHIN_S and (
                    sig == signal.SIGKILL or (len(lines) <= 1 and "Traceback" not in err)):
                out["clean stop"] += 1
            else:
                out["bad"].append(f"{sig.name} at {delay:.2f} s: exit {p.returncode} after {took:.1f} s, {len(lines)} lines: "
                                  f"{err.strip()[:200]!r}")
        r = subprocess.run(command(kind, cfg, store, backend), capture_output=True, text=True)
        got = table(store) if r.returncode == 0 else {}
        if r.returncode == 0 and same(got, ref):
            out["identical"] += 1
        else:
            out["bad"].append(f"resume after {sig.name} at {delay:.2f} s: exit {r.returncode} {r.stderr.strip()[:200]!r}"
                              f"{how_they_differ(got, ref) if r.returncode == 0 else ''}")
    out["duration_s"] = duration
    return out


def main(n: int, kinds: list[str]) -> None:
    tmp = Path(tempfile.mkdtemp())
    rng = random.Random(2026)
    print("| kind | backend | trials | interrupted | finished first | one line, right exit code, in time | "
          "resumed identical | longest stop (s) | uninterrupted run (s) |")
    print("|---|---|---|---|---|---|---|---|---|")
    problems = []
    for kind in kinds:
        _, text, _, backends = KINDS[kind]
        cfg = text if isinstance(text, Path) else tmp / f"{kind}.toml"
        if not isinstance(text, Path):
            cfg.write_text(text)
        for backend in backends:
            r = series(cfg, tmp, kind, backend, n, rng)
            print(f"| {kind} | {backend} | {r['trials']} | {r['interrupted']} | {r['finished first']} | "
                  f"{r['clean stop']}/{r['interrupted']} | {r['identical']}/{r['trials']} | {r['longest stop']:.1f} | "
                  f"{r['duration_s']:.1f} |", flush=True)
            problems += [f"{kind}/{backend}: {b}" for b in r["bad"]]
    for b in problems:
        print("-", b)


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 20, sys.argv[2:] or list(KINDS))
