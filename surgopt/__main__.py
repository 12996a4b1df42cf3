"""The ``surgopt`` command (and ``python -m surgopt``): stop signals are handled before anything else is
imported, so a Ctrl-C or SIGTERM at any instant, even while the CLI loads, ends in one line and its exit code."""
from __future__ import annotations



def main() -> None:
    from surgopt import interrupts

    interrupts.install()
    try:
        from surgopt.cli import run
    except BaseException as exc:  # noqa: BLE001 - stopped while loading: nothing ran, nothing to resume
        if interrupts.received() is None and not isinstance(exc, KeyboardInterrupt):
            raise  # a real import error
        interrupts.ignore()  # (a library may have wrapped the stop: pydantic-core's SchemaError)
        interrupts.exit_now(interrupts.report(exc if isinstance(exc, KeyboardInterrupt) else None, "nothing was run"))
    run()


if __name__ == "__main__":
    main()
