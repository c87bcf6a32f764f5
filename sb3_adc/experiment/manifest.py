"""
A checkpoint's manifest: the size and SHA-256 of each of its files, written after them, so that whether a checkpoint
is intact is known without unpickling anything (:func:`manifest_damage`). An integrity check, not a signature: the
files are still read by the restricted unpicklers of :mod:`~sb3_adc.experiment.restore`.
"""

from __future__ import annotations

import hashlib
import json
import os
from typing import Any

from sb3_adc.common.atomic import write_atomically
from sb3_adc.experiment.layout import Checkpoint

#: The manifest's format (a manifest of another format counts as absent: the checkpoint is checked by reading it).
MANIFEST_FORMAT = 1
#: A manifest is a few hundred bytes; a larger file is not one (and is not read into memory).
MAX_MANIFEST_BYTES = 64 * 1024


def _digest(path: str) -> dict[str, Any]:
    sha256 = hashlib.sha256()  # hashlib.file_digest needs Python 3.11
    with open(path, "rb") as stream:
        for block in iter(lambda: stream.read(1 << 20), b""):
            sha256.update(block)
    return {"bytes": os.path.getsize(path), "sha256": sha256.hexdigest()}


def _data_files(checkpoint: Checkpoint) -> list[str]:
    return [path for path in checkpoint.files if path != checkpoint.manifest and os.path.isfile(path)]


def write_manifest(checkpoint: Checkpoint) -> None:
    """
    Write the manifest of a checkpoint whose files are written (atomically, after them).

    :param checkpoint: The checkpoint
    """
    files = {os.path.basename(path): _digest(path) for path in _data_files(checkpoint)}
    content = json.dumps({"format": MANIFEST_FORMAT, "files": files}, indent=1)
    write_atomically(checkpoint.manifest, lambda stream: stream.write(content))


def manifest_damage(checkpoint: Checkpoint) -> str | None:
    """
    What the manifest finds wrong with a checkpoint's files (missing, another size or SHA-256, not listed), ``None``
    if they are the files it lists.

    :param checkpoint: The checkpoint
    :raises FileNotFoundError: if it has no manifest (only reading its files can tell)
    """
    name = os.path.basename(checkpoint.manifest)
    if os.path.getsize(checkpoint.manifest) > MAX_MANIFEST_BYTES:
        return f"{name} is larger than a manifest ({MAX_MANIFEST_BYTES} bytes)"
    try:
        with open(checkpoint.manifest, encoding="utf-8") as stream:
            manifest = json.load(stream)
        listed = manifest["files"]
        if manifest["format"] != MANIFEST_FORMAT or not isinstance(listed, dict):
            raise ValueError(f"not a manifest of format {MANIFEST_FORMAT}")
        if not all(isinstance(entry, dict) for entry in listed.values()):
            raise ValueError("an entry is not a file's size and SHA-256")
    except (ValueError, KeyError, TypeError, AttributeError) as error:  # JSON and UTF-8 errors are ValueErrors
        return f"{name} does not read ({type(error).__name__}: {error})"
    present = {os.path.basename(path): path for path in _data_files(checkpoint)}
    unlisted = sorted(set(present) - set(listed))
    if unlisted:
        return f"{unlisted[0]} is not in its manifest"
    for file, expected in listed.items():
        if file not in present:
            return f"{file} is missing (its manifest lists it)"
        actual = _digest(present[file])
        if actual != expected:
            what = "size" if actual["bytes"] != expected.get("bytes") else "SHA-256"
            return f"{file} does not match its manifest ({what} differs)"
    return None
