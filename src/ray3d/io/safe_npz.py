"""Read object entries of npz files (VideoPose3D-style nested dicts of arrays) without arbitrary unpickling.

Those files store ``{subject: {action: array}}`` as a pickled 0-d object array. ``np.load(allow_pickle=True)``
would execute whatever the pickle names; here only numpy arrays, dtypes and plain containers can be built, so a
hostile file fails with an error instead of running code.
"""

from __future__ import annotations

import io
import pickle
import zipfile
from pathlib import Path
from typing import Any

import numpy as np

from ray3d.errors import InputError

_ALLOWED = {
    ("numpy.core.multiarray", "_reconstruct"), ("numpy._core.multiarray", "_reconstruct"),
    ("numpy.core.multiarray", "scalar"), ("numpy._core.multiarray", "scalar"),
    ("numpy", "ndarray"), ("numpy", "dtype"), ("builtins", "dict"), ("builtins", "list"), ("builtins", "tuple"),
    ("collections", "OrderedDict"),
}


class _ArrayUnpickler(pickle.Unpickler):
    def find_class(self, module: str, name: str) -> Any:
        if (module, name) not in _ALLOWED:
            raise pickle.UnpicklingError(f"refusing to load {module}.{name}")
        return super().find_class(module, name)


def read_npz_entries(path: str | Path) -> dict[str, Any]:
    """Every entry of an npz: plain arrays as they are, object arrays as the containers they pickle."""
    path = Path(path)
    try:
        archive = zipfile.ZipFile(path)
    except (OSError, zipfile.BadZipFile) as err:
        raise InputError(f"{path}: not an npz file ({err})") from None
    entries: dict[str, Any] = {}
    with archive:
        for member in archive.namelist():
            key = member.removesuffix(".npy")
            with archive.open(member) as handle:
                stream = io.BytesIO(handle.read())
            try:
                version = np.lib.format.read_magic(stream)
                read_header = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                               else np.lib.format.read_array_header_2_0)
                _, _, dtype = read_header(stream)
            except ValueError as err:
                raise InputError(f"{path}: entry {key!r} is not a numpy array ({err})") from None
            if dtype.hasobject:
                try:
                    value = _ArrayUnpickler(stream).load()
                except (pickle.UnpicklingError, EOFError, AttributeError, ImportError) as err:
                    raise InputError(f"{path}: entry {key!r} holds objects other than arrays ({err})") from None
                entries[key] = value.item() if isinstance(value, np.ndarray) and value.shape == () else value
            else:
                stream.seek(0)
                entries[key] = np.lib.format.read_array(stream, allow_pickle=False)
    return entries
