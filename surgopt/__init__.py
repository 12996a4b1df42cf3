"""surgopt: kinematic design studies of surgical robots, batch-run with a cached result store.

The Python API (``surgopt.run``, ``load``, ``runs``, ``summarize``, ``plot``, ``diff``) is in ``surgopt.api``; it is
imported on first use so that ``import surgopt`` (and the CLI's --help) stays light.
"""

from surgopt._version import __version__
API = ("run", "load", "runs", "summarize", "plot", "diff")
__all__ = [*API, "__version__"]


def __getattr__(name):
    if name in API:
        from surgopt import api

        return getattr(api, name)
    raise AttributeError(f"module 'surgopt' has no attribute {name!r}")
