"""
Atomic file writes: a file is written under a temporary name next to it, then renamed over the target with
``os.replace``, so a reader (or a resumed run) sees the old file or the new one, never a half-written one.

This covers a process that is killed or crashes while writing; the data is not ``fsync``-ed, so it does not
cover a power failure.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Iterator
from typing import IO, Any

#: Inserted before the extension of a temporary file (a leftover one is the trace of a killed write; it is ignored).
PARTIAL_SUFFIX = ".partial"


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike[str]) -> Iterator[str]:
    """
    A temporary path to write ``path`` to: it replaces ``path`` when the ``with`` block ends without error,
    and is removed when the block raises.

    For writers that take a path, such as SB3's ``model.save``, ``save_replay_buffer``, ``VecNormalize.save``
    or NumPy's ``savez``: the temporary name keeps the target's extension (``model.zip`` is written as
    ``model.partial.zip``), since these writers add their extension to a name that lacks it.

    :param path: The file to write
    """
    target = os.fspath(path)
    root, extension = os.path.splitext(target)
    temporary = root + PARTIAL_SUFFIX + extension
    try:
        yield temporary
        os.replace(temporary, target)
    except BaseException:
        with contextlib.suppress(FileNotFoundError):
            os.remove(temporary)
        raise


def write_atomically(path: str | os.PathLike[str], write: Callable[[IO[Any]], object], binary: bool = False) -> None:
    """
    Write a file through an open stream, atomically (see :func:`atomic_path`).

    :param path: The file to write
    :param write: Writes the content to the stream it is given (its return value is ignored)
    :param binary: Open the stream in binary mode (else text, UTF-8, without newline translation)
    """
    with (
        atomic_path(path) as temporary,
        open(temporary, "wb") if binary else open(temporary, "w", encoding="utf-8", newline="") as stream,
    ):
        write(stream)
