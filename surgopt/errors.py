"""Errors the CLI turns into one-line messages and exit codes."""
from __future__ import annotations


#: The longest error message (a megabyte-long key or path named in one is cut, not echoed whole).
MAX_MESSAGE_CHARS = 2000


def capped(text: str, limit: int = MAX_MESSAGE_CHARS) -> str:
    """``text`` cut to ``limit`` characters, saying how long it was."""
    return text if len(text) <= limit else text[:limit] + f"... ({len(text):,} characters)"


def out_of_memory(exc: BaseException) -> bool:
    """A MemoryError, an import that could not map its shared object, a thread that could not be started, or an
    OS call refused for want of memory (ENOMEM): the address space ran out (``ulimit -v``)."""
    import errno

    return (isinstance(exc, MemoryError)
            or (isinstance(exc, ImportError) and "failed to map segment" in str(exc))
            or (isinstance(exc, RuntimeError) and "can't start new thread" in str(exc))
            or (isinstance(exc, OSError) and exc.errno == errno.ENOMEM))


class SurgoptError(Exception):
    """Base class: ``exit_code`` is what the CLI exits with; the message is capped at MAX_MESSAGE_CHARS."""

    exit_code = 1

    def __str__(self) -> str:
        return capped(super().__str__())


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
