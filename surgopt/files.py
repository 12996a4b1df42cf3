"""Reading a file a user or the store names: regular files only, their size checked before anything is
read, and a bound on how much is read (a FIFO never blocks, /dev/zero or an 8 GB file is never read whole)."""
from __future__ import annotations

import contextlib
import errno
import os
from pathlib import Path


class FileProblem(ValueError):
    """A path that is not a regular file of an acceptable size; the message names it."""


def read_bounded(path: Path, limit: int, expected: int | None = None) -> bytes:
    """The bytes of ``path`` if it is a regular file (a link to one counts) of at most ``limit`` bytes (and of
    exactly ``expected`` bytes when given), else FileProblem; size and kind are checked before anything is
    read, so a FIFO, a device such as /dev/zero or an oversized file is never read. FileNotFoundError and
    IsADirectoryError pass through for callers that handle them."""
    import stat

    fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)  # a FIFO must not block the open itself
    try:
        st = os.fstat(fd)
        if stat.S_ISDIR(st.st_mode):
            raise IsADirectoryError(errno.EISDIR, "is a folder", str(path))
        if not stat.S_ISREG(st.st_mode):
            raise FileProblem(f"{path}: not a regular file (a device, FIFO or socket); not read")
        if expected is not None and st.st_size != expected:
            raise FileProblem(f"{path}: has {st.st_size} bytes where {expected} were expected")
        if st.st_size > limit:
            raise FileProblem(f"{path}: {st.st_size:,} bytes, more than the {limit:,} such a file can have")
        os.set_blocking(fd, True)
        chunks, size = [], 0
        while size <= limit:
            b = os.read(fd, min(1 << 24, limit + 1 - size))
            if not b:
                break
            chunks.append(b)
            size += len(b)
        if size > limit:  # grew while read
            raise FileProblem(f"{path}: more than the {limit:,} bytes such a file can have")
        return b"".join(chunks)
    finally:
        os.close(fd)


#: The config fields that name a file (resolved by ``resolve_and_hash`` against the folder of the config that
#: gave them): a layered config (several CONFIG files) resolves each layer's own against its own folder.
FILE_FIELDS = ("urdf", "mesh_file", "points_file")


def config_file_path(value: str, context: dict) -> Path:
    """A file a config names, as an absolute path: relative paths are taken from the config file's folder
    (``context["config_dir"]``), or the working directory for overrides and embedded configs."""
    path = Path(value).expanduser()
    if not path.is_absolute():
        path = Path(context.get("config_dir") or Path.cwd()) / path
    real = path.resolve()
    if _read_files is not None and real != path:  # a link (the file's, a folder's on the way): what it names now
        _read_files.append((str(path), str(real), ""))  # is checked again by a cache hit (its contents by its read)
    return real


#: While a command records (``recording``): (path, sha256) of every file a config was read from or named.
_read_files: list | None = None


@contextlib.contextmanager
def recording():
    """The files configs read while inside, as a list of (path as named, the file it resolved to, sha256) filled
    in as they are read:
    what a cache hit answered before the config is validated must find unchanged (``surgopt.hits``)."""
    global _read_files
    outer, _read_files = _read_files, []
    try:
        yield _read_files
    finally:
        _read_files = outer


def note_read(path: Path, data: bytes) -> bytes:
    """``data`` as read from ``path`` for a config, noted while ``recording`` as (the path as it was named, the file
    it resolved to, the sha256): a cache hit resolves the named path again (issue 55 item 3: a link retargeted is
    another file, whatever the old one holds)."""
    if _read_files is not None:
        import hashlib

        _read_files.append((str(path), str(Path(path).resolve()), hashlib.sha256(data).hexdigest()))
    return data


def read_config_file(field: str, path: Path, limit: int) -> bytes:
    """The bytes of a file a config names (``read_bounded``); every failure a ValueError naming ``field``."""
    try:
        return note_read(path, read_bounded(path, limit))
    except FileNotFoundError:
        raise ValueError(f"{field}: file not found: {path}") from None
    except FileProblem as exc:
        raise ValueError(f"{field}: {exc}") from None
    except OSError as exc:
        raise ValueError(f"{field}: cannot read {path}: {exc.strerror or exc}") from None


def hashed_config_file(field: str, path: Path, sha256: str | None, limit: int, sha_field: str) -> tuple[bytes, str]:
    """(bytes, sha256) of a file a config names, held to the ``sha256`` the config already carries (a stored or
    printed config): a file changed since is a ValueError naming ``field`` and how to accept the change."""
    import hashlib

    data = read_config_file(field, path, limit)
    sha = hashlib.sha256(data).hexdigest()
    if sha256 is not None and sha256 != sha:
        raise ValueError(f"{field}: {path} changed since this config was written ({sha_field} differs); drop "
                         f"{sha_field} to use the file as it is now")
    return data, sha


def resolve_and_hash(model, field: str, sha_field: str, limit: int, context: dict) -> tuple[Path, str | None]:
    """The file a config model's ``field`` names, resolved against the config's folder (``config_file_path``)
    and set back on the model as an absolute path; unless the config is read as stored (``context["stored"]``),
    read (bounded by ``limit`` bytes), hashed and held to the hash the model already carries, the hash set into
    ``sha_field``. (path, sha256; None when stored.) The one way a config takes in a file (a URDF, a mesh, a
    points file): its content, not its path, goes into the store key."""
    path = config_file_path(getattr(model, field), context)
    object.__setattr__(model, field, str(path))
    if context.get("stored"):
        return path, None
    _, sha = hashed_config_file(field, path, getattr(model, sha_field), limit, sha_field)
    object.__setattr__(model, sha_field, sha)
    return path, sha
