"""The ``surgopt`` command (and ``python -m surgopt``): stop signals are handled before anything else is
imported, so a Ctrl-C or SIGTERM at any instant, even while the CLI loads, ends in one line and its exit code."""
from __future__ import annotations

import sys


def main() -> None:
    from surgopt import interrupts

    interrupts.install()
    try:
        from surgopt.cli import run
    except KeyboardInterrupt as exc:  # stopped while loading: nothing ran, nothing to resume
        interrupts.ignore()
        sys.exit(interrupts.report(exc, "nothing was run"))
    run()


if __name__ == "__main__":
    main()
