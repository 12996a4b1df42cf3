"""What identifies the code that computes a run's rows: a sha256 over the source of the kernels, the robot
models, the study declarations and the modules they read (the store key includes it, so an edited kernel or
model in an editable install is never served the old rows), and the git commit of a checkout (recorded in
each manifest, as MLflow and DVC record theirs)."""
from __future__ import annotations

import hashlib
from functools import lru_cache
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent
#: The package paths whose source computes rows (a plan chooses which designs a search evaluates; figures, the
#: CLI, the backends, the store and the reports do not).
ROW_CODE = ("kinematics", "robots", "studies", "plans", "metrics.py", "jit.py")


#: The files of a study folder that draw, not compute (a figure or a page changes no row).
DRAWING = ("figures.py", "html.py", "plotting.py")


def row_code_files() -> list[Path]:
    """Every source file under ROW_CODE, in a fixed order (the DRAWING files left out)."""
    files = []
    for name in ROW_CODE:
        path = PACKAGE / name
        if path.is_file():
            files.append(path)
        else:
            files += [f for f in path.rglob("*.py") if f.name not in DRAWING]
    return sorted(files)


@lru_cache(maxsize=1)
def code_sha256() -> str:
    """sha256 over the names and bytes of ``row_code_files()``."""
    h = hashlib.sha256()
    for f in row_code_files():
        h.update(str(f.relative_to(PACKAGE)).encode() + b"\0" + f.read_bytes() + b"\0")
    return h.hexdigest()


@lru_cache(maxsize=1)
def git_commit() -> str | None:
    """The commit of the checkout the package runs from (an editable install), with '+dirty' when its row code
    has uncommitted changes; None outside a checkout or without git."""
    import subprocess

    top = PACKAGE.parent
    if not (top / ".git").exists():
        return None
    try:
        head = subprocess.run(["git", "-C", str(top), "rev-parse", "HEAD"], capture_output=True, text=True,
                              timeout=5).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(top), "status", "--porcelain", "--", *(f"surgopt/{n}" for n in ROW_CODE)],
                               capture_output=True, text=True, timeout=5).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None
    return (head + ("+dirty" if dirty else "")) if head else None
