"""surgopt: kinematic design studies of surgical robots, batch-run with a cached result store."""

__version__ = "0.1.0"
