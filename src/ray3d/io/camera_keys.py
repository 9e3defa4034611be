"""The keys of camera files (issue 68): every key a camera file of ours carries, and the check that refuses any
other with the key it most likely meant, so that a misspelt ``"dsit"`` or ``"floor_zm"`` never silently drops the
lens or the floor (``assets/camera.schema.json`` names the same keys; tests/test_camera_keys.py holds them
together); and the near misses of an OpenCV camera's fields."""

from __future__ import annotations

import difflib
from pathlib import Path
from typing import Any

from ray3d.errors import InputError
from ray3d.geometry.camera_parameters import DICT_FIELDS

FLOOR_KEY = "floor_regions"
FLOOR_Z_KEY = "floor_z_m"
FLOOR_CHECK_KEY = "floor_check"
# Every key a camera file of ours carries. A camera: ``Camera.to_dict``'s fields. Beside the camera(s), for the
# whole file: its floor regions, where its floor lies and how that was settled (``ray3d calibrate --floor-of``). A
# list of cameras may also say how it was made: ``ray3d cameras`` (set, filter), ``ray3d calibrate --floor-points``
# (reprojection_rms_px), ``ray3d calibrate --from-person`` (calibration, person_height_m, tracks and
# ``PersonCalibration.to_dict``), and a name or description anyone may add (one camera: a description). A key
# starting with "_" is a comment, anywhere.
CAMERA_KEYS = ("name", *DICT_FIELDS)
FILE_KEYS = (FLOOR_KEY, FLOOR_Z_KEY, FLOOR_CHECK_KEY)
SINGLE_INFO_KEYS = ("description",)
LIST_INFO_KEYS = ("name", "description", "set", "filter", "reprojection_rms_px", "calibration", "person_height_m",
                  "tracks", "height_m", "pitch_deg", "roll_deg", "focal_px", "height_sd_m", "pitch_sd_deg",
                  "roll_sd_deg", "focal_sd_px", "rms_px", "frames_used", "people", "warnings")


def _is_comment(key: Any) -> bool:
    return isinstance(key, str) and key.startswith("_")


def _closest(key: str, candidates) -> str | None:
    """The candidate ``key`` most likely misspells (the same but for case, else the closest by
    ``difflib.get_close_matches``), None when none is close."""
    candidates = [str(c) for c in candidates if c != key]
    same = [c for c in candidates if c.lower() == key.lower()]
    close = same or difflib.get_close_matches(key, candidates, n=1, cutoff=0.6)
    return close[0] if close else None


def _check_keys(entry: dict, where: str, allowed: tuple[str, ...], required: tuple[str, ...] = ()) -> None:
    """Refuse, naming ``where``, a key of ``entry`` that is not ``allowed`` (with the known key it most likely
    meant), and a ``required`` field that is missing where another key is probably its misspelling."""
    unknown = [str(key) for key in entry if key not in allowed and not _is_comment(key)]
    for field in (f for f in required if f not in entry):
        meant = _closest(field, unknown)
        if meant is not None:
            raise InputError(f"{where}: missing field {field}: unknown key {meant!r} (did you mean {field!r}?)")
    if unknown:
        key = unknown[0]
        if key in FILE_KEYS:
            raise InputError(f"{where}: {key!r} belongs at the file's top level, beside \"cameras\" (it applies to "
                             "every camera of the file)")
        meant = _closest(key, allowed)
        raise InputError(f"{where}: unknown key {key!r}" + (f" (did you mean {meant!r}?)" if meant else
                                                            f"; the keys here are {', '.join(allowed)}"))


def check_camera_document(document: Any, path: str | Path) -> None:
    """A camera file of ours (JSON: one camera, ``{"cameras": [...]}`` or floor regions alone) refused, naming the
    file and the key, when it holds a key ray3d does not know (``"dsit"``, ``"floor_zm"``: the lens or the floor
    would be silently dropped), with the key it most likely meant; a missing camera field is named with the key
    that probably meant it. Anything else about it is checked where it is read."""
    if not isinstance(document, dict) or "camera_matrix" in document:  # OpenCV's: refuse_near_misses
        return
    if "cameras" in document:
        _check_keys(document, f"{path}", ("cameras", *FILE_KEYS, *LIST_INFO_KEYS))
        if isinstance(document["cameras"], list):
            for i, entry in enumerate(document["cameras"]):
                if isinstance(entry, dict):
                    _check_keys(entry, f"{path}: camera {i}", CAMERA_KEYS, DICT_FIELDS)
        return
    looks_like_a_camera = any(key in document for key in DICT_FIELDS) or any(
        _closest(str(key), DICT_FIELDS) for key in document if key not in (*CAMERA_KEYS, *FILE_KEYS)
        and not _is_comment(key))
    if looks_like_a_camera:
        _check_keys(document, f"{path}", (*CAMERA_KEYS, *FILE_KEYS, *SINGLE_INFO_KEYS), DICT_FIELDS)
    elif FLOOR_KEY in document or any(difflib.get_close_matches(str(key), (FLOOR_KEY,), cutoff=0.8)
                                      for key in document):  # floor regions alone
        _check_keys(document, f"{path}", (FLOOR_KEY, "name", "description"), (FLOOR_KEY,))


def refuse_near_misses(fields: dict, path: Path) -> None:
    """An OpenCV camera (other tools write more than we read, so other keys pass) refused when a key is a
    near-certain misspelling of a field it lacks (``dist_coefs``: its lens would be silently dropped)."""
    for key in fields:
        if not isinstance(key, str) or key in OPENCV_FIELDS or _is_comment(key):
            continue
        close = difflib.get_close_matches(key, OPENCV_FIELDS, n=1, cutoff=0.85)
        if close and not any(close[0] in group and set(group) & set(fields) for group in _OPENCV_ALTERNATIVES):
            raise InputError(f"{path}: unknown key {key!r} (did you mean {close[0]!r}?)")


OPENCV_FIELDS = ("camera_matrix", "dist_coeffs", "distortion_coefficients", "rvec", "tvec", "R", "t",
                 "image_width", "image_height", "width", "height")
# Each OpenCV field and the others that say the same: a key near one of a group that is given is not its typo
# (a calibration's per-view "rvecs" beside "R").
_OPENCV_ALTERNATIVES = (("camera_matrix",), ("dist_coeffs", "distortion_coefficients"), ("rvec", "R"), ("tvec", "t"),
                        ("image_width", "width"), ("image_height", "height"))
