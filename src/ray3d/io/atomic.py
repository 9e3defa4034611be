"""Atomic file writes: write beside the target, then rename, so a crash never leaves half a file and an
existing output is only replaced when asked. The file gets the permissions the user's umask gives a new file
(a temporary file starts private, readable by its owner only)."""

from __future__ import annotations

import contextlib
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path

from ray3d.errors import InputError


def _umask() -> int:
    """The process's umask (reading it means setting it: set it straight back)."""
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def check_output(target: str | Path, inputs: tuple = (), argument: str = "out") -> Path:
    """Refuse, before any work, an output path that is one of the ``inputs`` (files or folders read), is an
    existing folder, or lies below a file; returns it as a ``Path``."""
    target = Path(target)
    resolved = target.resolve()
    for source in inputs:
        if source is not None and Path(source).exists() and Path(source).resolve() == resolved:
            raise InputError(f"{target}: is also an input; writing it would destroy what was read",
                             arguments=(argument,))
    if target.is_dir():
        raise InputError(f"{target}: is a folder; give a file name", arguments=(argument,))
    for parent in resolved.parents:
        if parent.exists() and not parent.is_dir():
            raise InputError(f"{target}: {parent} is a file, not a folder", arguments=(argument,))
    return target


def refuse_existing(target: str | Path, overwrite: bool) -> Path:
    """Refuse ``target`` if it exists and ``overwrite`` is False (before any work is done for it)."""
    target = Path(target)
    if target.exists() and not overwrite:
        raise InputError(f"{target}: already exists; refusing to overwrite it", arguments=("overwrite",))
    return target


@contextlib.contextmanager
def atomic_path(target: str | Path, overwrite: bool = False) -> Iterator[Path]:
    """Yield a temporary path in ``target``'s folder; on success it is renamed to ``target``.

    Raises:
        InputError: if ``target`` exists and ``overwrite`` is False.
    """
    target = refuse_existing(target, overwrite)
    target.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp" + target.suffix, dir=target.parent)
    os.close(handle)
    try:
        yield Path(temporary)
        os.chmod(temporary, 0o666 & ~_umask())
        os.replace(temporary, target)
    finally:
        if os.path.exists(temporary):
            os.unlink(temporary)


def write_text(target: str | Path, text: str, overwrite: bool = False) -> Path:
    """``text`` written to ``target`` atomically (``atomic_path``)."""
    target = Path(target)
    with atomic_path(target, overwrite) as temporary:
        temporary.write_text(text)
    return target
