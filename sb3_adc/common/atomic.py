"""
Atomic file writes: a file is written under a temporary name next to it, then renamed over the target with
``os.replace``, so a reader (or a resumed run) sees the old file or the new one, never a half-written one.

The temporary file is created exclusively (``O_CREAT | O_EXCL | O_NOFOLLOW``) after whatever was at its name (a
leftover of a killed write, or a link planted there) is unlinked, so a write never goes through a link to a file
outside the target's folder. Its data is ``fsync``-ed before the rename, and the folder after it (where the
platform allows), so a power failure leaves the old file or the new one too.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Iterator
from typing import IO, Any

#: Inserted before the extension of a temporary file (a leftover one is the trace of a killed write; it is ignored).
PARTIAL_SUFFIX = ".partial"
#: Flags that create a file only where nothing (not even a dangling link) is at its name, without following links.
_EXCLUSIVE = os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_BINARY", 0)


def temporary_name(path: str | os.PathLike[str]) -> str:
    """
    The temporary name ``path`` is written under: the target's name with :data:`PARTIAL_SUFFIX` before its
    extension (``model.zip`` is written as ``model.partial.zip``).

    :param path: The file to write
    """
    root, extension = os.path.splitext(os.fspath(path))
    return root + PARTIAL_SUFFIX + extension


def _create_exclusively(temporary: str) -> int:
    """
    Create ``temporary`` as a new, empty regular file and return its descriptor, open for writing.

    Whatever is at that name (a leftover file, a link) is unlinked first: the link itself, never its target.

    :raises FileExistsError: where something appears at that name between the unlink and the creation
    """
    with contextlib.suppress(FileNotFoundError):
        os.unlink(temporary)
    return os.open(temporary, _EXCLUSIVE, 0o666)


def _fsync_folder(folder: str) -> None:
    """Make a rename in ``folder`` durable, where the platform can open a folder (not on Windows)."""
    try:
        descriptor = os.open(folder or ".", os.O_RDONLY)
    except OSError:
        return
    try:
        with contextlib.suppress(OSError):
            os.fsync(descriptor)
    finally:
        os.close(descriptor)


def _commit(temporary: str, target: str) -> None:
    """``fsync`` the written ``temporary`` file (without following a link), rename it over ``target``."""
    descriptor = os.open(temporary, os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_BINARY", 0))
    try:
        os.fsync(descriptor)
    finally:
        os.close(descriptor)
    os.replace(temporary, target)
    _fsync_folder(os.path.dirname(target))


def _name_target(error: BaseException, target: str) -> None:
    """
    Name ``target`` in an ``OSError`` of the system that names no file (a full disk fails a ``write`` or ``flush``,
    which knows no name), so that its message says which file could not be written.
    """
    if isinstance(error, OSError) and error.errno is not None and error.filename is None:
        error.filename = target


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[str]:
    """
    A temporary path to write ``path`` to: it replaces ``path`` when the ``with`` block ends without error,
    and is removed when the block raises.

    For writers that take a path, such as SB3's ``model.save``, ``save_replay_buffer``, ``VecNormalize.save``
    or NumPy's ``savez``: the temporary name keeps the target's extension (see :func:`temporary_name`), since
    these writers add their extension to a name that lacks it. The temporary file exists, empty, when the block
    starts: created exclusively, so the writer writes to a new file in the target's folder, never through a link.

    :param path: The file to write
    """
    target = os.fspath(path)
    temporary = temporary_name(target)
    os.close(_create_exclusively(temporary))
    try:
        yield temporary
        _commit(temporary, target)
    except BaseException as error:
        with contextlib.suppress(FileNotFoundError):
            os.remove(temporary)
        _name_target(error, target)
        raise


def write_atomically(path: str | os.PathLike[str], write: Callable[[IO[Any]], object], binary: bool = False) -> None:
    """
    Write a file through an open stream, atomically (see :func:`atomic_path`).

    The stream is the exclusively created temporary file itself (the name is not opened again).

    :param path: The file to write
    :param write: Writes the content to the stream it is given (its return value is ignored)
    :param binary: Open the stream in binary mode (else text, UTF-8, without newline translation)
    """
    target = os.fspath(path)
    temporary = temporary_name(target)
    descriptor = _create_exclusively(temporary)
    try:
        try:
            stream = os.fdopen(descriptor, "wb") if binary else os.fdopen(descriptor, "w", encoding="utf-8", newline="")
        except BaseException:
            os.close(descriptor)
            raise
        with stream:
            write(stream)
            stream.flush()
            os.fsync(stream.fileno())
        os.replace(temporary, target)
        _fsync_folder(os.path.dirname(target))
    except BaseException as error:
        with contextlib.suppress(FileNotFoundError):
            os.remove(temporary)
        _name_target(error, target)
        raise
