"""Errors the CLI turns into one-line messages and exit codes."""
from __future__ import annotations


class SurgoptError(Exception):
    """Base class: ``exit_code`` is what the CLI exits with."""

    exit_code = 1


class ConfigError(SurgoptError):
    """A config file that is missing, unparsable or invalid (exit code 2)."""

    exit_code = 2

    def __init__(self, source: str, message: str, field: str | None = None):
        self.source = source
        self.field = field
        where = f"{source}: {field}: " if field else f"{source}: "
        super().__init__(where + message)


class UsageError(SurgoptError):
    """Bad command-line input other than a config file (exit code 2)."""

    exit_code = 2


class StoreError(SurgoptError):
    """A store that is corrupt or cannot be written (exit code 1)."""
