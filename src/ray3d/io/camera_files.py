"""Camera files (ours, OpenCV JSON / YAML, calibration TOML), camera lists as JSON (``{"cameras": [camera, ...]}``
with each camera in ``Camera.to_dict`` form), the floor regions a file declares, and the one builder of a job's
camera from its options."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any
from xml.etree import ElementTree

import cv2
import numpy as np
import yaml

from ray3d.errors import InputError, reads_file
from ray3d.geometry import Camera, parse_image_size
from ray3d.geometry.arrays import numeric_array
from ray3d.geometry.floor import FLAT_FLOOR, Floor, FloorRegion, checked_floor_z
from ray3d.io.atomic import atomic_path, check_output
from ray3d.io.camera_keys import FLOOR_KEY, FLOOR_Z_KEY, OPENCV_FIELDS, check_camera_document, refuse_near_misses
from ray3d.io.text_files import read_json


def save_cameras(path: str | Path, cams: list[Camera], overwrite: bool = False, **info: Any) -> None:
    """Write cameras (and any extra top-level ``info``) atomically."""
    with atomic_path(path, overwrite) as temporary:
        temporary.write_text(json.dumps({**info, "cameras": [c.to_dict() for c in cams]}, indent=1))


@reads_file("camera file")
def load_cameras(path: str | Path) -> list[Camera]:
    """Read a camera list, or a single camera object, from JSON."""
    path = Path(path)
    document = read_json(path)
    check_camera_document(document, path)
    entries = document.get("cameras", [document]) if isinstance(document, dict) else document
    if not isinstance(entries, list) or not entries:
        raise InputError(f"{path}: expected a camera object or {{\"cameras\": [...]}}")
    if isinstance(document, dict) and "cameras" not in document and "fx" not in document:
        raise InputError(f"{path}: camera without intrinsics: expected fx, fy, cx, cy (or an OpenCV camera_matrix)")
    cams = []
    for i, entry in enumerate(entries):
        try:
            cams.append(Camera.from_dict(entry, name=f"{path.stem}:{i}"))
        except InputError as err:
            raise InputError(f"{path}: camera {i}: {err}") from None
    return cams


def _matrix(value: Any, path: Path, field: str, sizes: tuple[int, ...]) -> np.ndarray:
    """A field's finite numbers from a nested list, a flat list, or OpenCV's JSON {rows, cols, data}, checked to
    hold one of ``sizes`` numbers before anything reshapes them."""
    if isinstance(value, dict):
        if "data" not in value:
            raise InputError(f"{path}: {field}: expected a list of numbers or OpenCV's {{rows, cols, data}}, got an "
                             f"object without data")
        rows, cols = value.get("rows", 1), value.get("cols", None)
        for name, size in (("rows", rows), ("cols", cols)):  # given, each must be a size (null is not one)
            if name in value and (isinstance(size, bool) or not isinstance(size, int) or not 0 < size <= 16):
                raise InputError(f"{path}: {field}.{name}: expected a whole number 1-16, got {_shown(size)}")
        if not isinstance(value["data"], list):
            raise InputError(f"{path}: {field}.data: expected a list of numbers, got {_shown(value['data'])}")
        data = numeric_array(value["data"], f"{path}: {field}.data").ravel()
        if cols is not None and data.size != rows * cols:
            raise InputError(f"{path}: {field}: {rows} x {cols} needs {rows * cols} numbers in data, got {data.size}")
    elif not isinstance(value, (list, tuple, np.ndarray)):
        raise InputError(f"{path}: {field}: expected a list of numbers, got {_shown(value)}")
    else:
        data = numeric_array(value, f"{path}: {field}").ravel()
    if data.size not in sizes:
        expected = " or ".join(str(n) for n in sizes) if len(sizes) < 4 else f"{sizes[0]}-{sizes[-1]}"
        raise InputError(f"{path}: {field}: expected {expected} numbers, got {data.size}")
    if not np.isfinite(data).all():
        raise InputError(f"{path}: {field}: contains NaN or infinite values")
    return data


def _shown(value: Any) -> str:
    """A value as the file wrote it, short: JSON's null, not Python's None."""
    text = "null" if value is None else repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _image_side(value: Any, path: Path, field: str) -> int:
    """A positive whole number of pixels (an integral float as OpenCV's readers give it is one)."""
    # Compared before anything converts it: JSON's whole numbers have no bound, NaN and infinity fail the range.
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not 0 < value <= 1_000_000 or value != int(value):
        raise InputError(f"{path}: {field}: expected a positive whole number of pixels, got {value!r}")
    return int(value)


def _from_opencv_fields(fields: dict[str, Any], path: Path) -> Camera:
    if "camera_matrix" not in fields:
        raise InputError(f"{path}: camera without intrinsics: expected 'camera_matrix' (or fx, fy, cx, cy)")
    K = _matrix(fields["camera_matrix"], path, "camera_matrix", (9,)).reshape(3, 3)
    dist = _matrix(fields.get("dist_coeffs", fields.get("distortion_coefficients", np.zeros(5))), path,
                   "dist_coeffs", tuple(range(15)))
    if dist.size > 5:
        if np.any(dist[5:] != 0):
            raise InputError(f"{path}: dist_coeffs: only k1, k2, p1, p2, k3 are supported; the rational or thin-prism "
                             "terms beyond are non-zero")
        dist = dist[:5]
    if "R" in fields:
        R = _matrix(fields["R"], path, "R", (9,)).reshape(3, 3)
    elif "rvec" in fields:
        R, _ = cv2.Rodrigues(_matrix(fields["rvec"], path, "rvec", (3,)).reshape(3, 1))
    else:
        raise InputError(f"{path}: camera without extrinsics: expected 'rvec' and 'tvec' or 'R' and 't' "
                         "(world -> camera, metres)")
    t_field = "tvec" if "tvec" in fields else "t"
    if t_field not in fields:
        raise InputError(f"{path}: camera without translation: expected 'tvec' or 't' (metres)")
    t = _matrix(fields[t_field], path, t_field, (3,))
    sides = {}
    for side, names in (("width", ("image_width", "width")), ("height", ("image_height", "height"))):
        name = next((n for n in names if n in fields), None)
        if name is None:
            raise InputError(f"{path}: camera without image size: expected image_width and image_height")
        sides[side] = _image_side(fields[name], path, name)
    return Camera(K, dist, R, t, (sides["width"], sides["height"]), name=path.stem)


class _OpenCVYaml(yaml.SafeLoader):
    """YAML as OpenCV's FileStorage writes it: an ``!!opencv-matrix`` is its mapping {rows, cols, dt, data}."""


_OpenCVYaml.add_constructor("tag:yaml.org,2002:opencv-matrix",
                            lambda loader, node: loader.construct_mapping(node, deep=True))


def _xml_scalar(text: str | None) -> Any:
    """An XML element's text as a whole number, else a number, else the text itself (None when empty): what is
    not a number is then refused naming its field, as in the YAML and JSON forms."""
    text = (text or "").strip()
    for number in (int, float):
        try:
            return number(text)
        except ValueError:
            pass
    return text or None


def _opencv_xml_fields(text: str) -> dict[str, Any]:
    """The top-level fields of OpenCV's XML storage: a matrix (``type_id="opencv-matrix"``) as {rows, cols,
    data}, anything else as its value."""
    fields: dict[str, Any] = {}
    for element in ElementTree.fromstring(text):
        if element.get("type_id") == "opencv-matrix":
            fields[element.tag] = {"rows": _xml_scalar(element.findtext("rows")),
                                   "cols": _xml_scalar(element.findtext("cols")),
                                   "data": [_xml_scalar(v) for v in element.findtext("data", "").split()]}
        else:
            fields[element.tag] = _xml_scalar(element.text)
    return fields


@reads_file("OpenCV camera file")
def _read_opencv_storage(path: Path) -> Camera:
    """An OpenCV YAML / XML camera, parsed here (PyYAML, ElementTree), not by OpenCV's FileStorage: its parser
    aborts the process on a negative ``rows`` and corrupts its heap on some broken files (benchmarks/
    fuzz_readers.py), which no ``try`` can catch."""
    if path.stat().st_size > 1_000_000:
        raise InputError(f"{path}: {path.stat().st_size} bytes is too large for a camera file")
    text = path.read_text()
    if not text.strip():
        raise InputError(f"{path}: empty file")
    if path.suffix.lower() == ".xml":
        document = _opencv_xml_fields(text)
    else:  # OpenCV's "%YAML:1.0" directive is not YAML 1.1's
        document = yaml.load("\n".join(line for line in text.splitlines() if not line.startswith("%YAML")),
                             Loader=_OpenCVYaml)
    if not isinstance(document, dict):
        raise InputError(f"{path}: not an OpenCV camera file (expected fields such as camera_matrix at the top)")
    refuse_near_misses(document, path)
    return _from_opencv_fields({k: v for k, v in document.items() if k in OPENCV_FIELDS and v is not None}, path)


@reads_file("calibration TOML")
def read_calibration_toml(path: str | Path, name: str | None = None) -> Camera:
    """The camera called ``name`` (its section or its ``name`` field; optional when the file holds one) of a
    Pose2Sim / Anipose / FreeMoCap calibration TOML: ``matrix`` (K), ``distortions`` (k1, k2, p1, p2),
    ``rotation`` (a Rodrigues vector) and ``translation`` (metres), world -> camera as OpenCV's
    ``projectPoints`` takes them, and ``size`` (width, height)."""
    import tomllib

    path = Path(path)
    with path.open("rb") as handle:
        document = tomllib.load(handle)
    sections = {key: value for key, value in document.items() if isinstance(value, dict) and "matrix" in value}
    if not sections:
        raise InputError(f"{path}: no camera sections (tables with matrix, distortions, rotation, translation)")
    if name is None:
        if len(sections) > 1:
            raise InputError(f"{path}: holds cameras {', '.join(sections)}; name one ({path}:NAME)",
                             arguments=("camera",))
        name = next(iter(sections))
    wanted = [key for key, value in sections.items() if str(name) in (key, str(value.get("name")))
              or str(name).replace("_", "") == key.replace("_", "")]
    if not wanted:
        raise InputError(f"{path}: no camera {name!r}; it holds {', '.join(sections)}", arguments=("camera",))
    section = sections[wanted[0]]
    where = f"{path}: [{wanted[0]}]"
    if section.get("fisheye"):
        raise InputError(f"{where}: a fisheye lens; ray3d's lens model is OpenCV's pinhole with radial and "
                         "tangential distortion")
    K = _matrix(section.get("matrix"), path, f"[{wanted[0]}] matrix", (9,)).reshape(3, 3)
    R, _ = cv2.Rodrigues(_matrix(section.get("rotation"), path, f"[{wanted[0]}] rotation (Rodrigues)", (3,)))
    size = parse_image_size(
        _matrix(section.get("size"), path, f"[{wanted[0]}] size", (2,)).round().astype(int).tolist(), f"{where} size")
    try:
        return Camera.from_intrinsics(K[0, 0], K[1, 1], K[0, 2], K[1, 2], section.get("distortions", [0.0] * 4), R,
                                      section.get("translation"), size, name=str(section.get("name", wanted[0])))
    except InputError as err:
        raise InputError(f"{where}: {err.message}") from None


def read_camera(spec: str | Path, index: int = 0) -> Camera:
    """One camera from ``h36m:SUBJECT:CAMERA_ID``, our JSON (one camera or {"cameras": [...]}: ``index``),
    OpenCV-style JSON (camera_matrix, dist_coeffs, rvec/tvec or R/t, image_width/height), OpenCV YAML, or a
    calibration TOML (Pose2Sim, Anipose, FreeMoCap) as ``FILE.toml:NAME`` (``FILE.toml`` alone when it holds one
    camera)."""
    text = str(spec)
    toml_file, _, toml_name = text.rpartition(":")
    if toml_file.lower().endswith(".toml") and Path(toml_file).is_file():
        return read_calibration_toml(toml_file, toml_name)
    if text.lower().endswith(".toml") and Path(text).is_file():
        return read_calibration_toml(text)
    if text.startswith("h36m:"):
        parts = text.split(":")
        if len(parts) != 3:
            raise InputError(f"camera {text!r}: expected h36m:SUBJECT:CAMERA_ID, e.g. h36m:S9:54138969")
        from ray3d import cameras

        return cameras.h36m(parts[1], parts[2])
    path = Path(spec)
    if not path.is_file():
        raise InputError(f"{path}: no such camera file")
    if path.suffix.lower() in (".yaml", ".yml", ".xml"):
        return _read_opencv_storage(path)
    document = read_json(path)
    if isinstance(document, dict) and "camera_matrix" in document:
        refuse_near_misses(document, path)
        return _from_opencv_fields(document, path)
    cams = load_cameras(path)
    if not 0 <= index < len(cams):
        raise InputError(f"{path}: holds {len(cams)} camera(s); index {index} is out of range")
    return cams[index]


def camera_from_options(camera: str | Path | None = None, camera_height: float | None = None,
                        pitch: float | None = None, image_size: Any = None, roll: float | None = None,
                        focal: float | None = None, hfov: float | None = None,
                        default_image_size: tuple[int, int] | None = None) -> Camera:
    """The camera of a job, as its options give it: a camera file (or ``h36m:SUBJECT:CAMERA_ID``), or a camera
    placed by ``camera_height`` (m), ``pitch`` and ``roll`` (degrees) and ``hfov`` (degrees) or ``focal``
    (pixels) for images ``image_size`` (``WIDTHxHEIGHT`` or a pair; a video's own, ``default_image_size``,
    when not given). The one builder behind ``ray3d lift``, ``ray3d video`` and batch manifests: a camera whose
    lens cannot be inverted over its image is refused (``Camera.doubts``; what is only implausible the caller
    warns of)."""
    built = _camera_of_options(camera, camera_height, pitch, image_size, roll, focal, hfov, default_image_size)
    unusable, _ = built.doubts()
    if unusable:
        raise InputError(unusable[0], arguments=("camera",))
    return built


def _camera_of_options(camera, camera_height, pitch, image_size, roll, focal, hfov, default_image_size) -> Camera:
    placed = {"camera_height": camera_height, "pitch": pitch, "roll": roll, "focal": focal, "hfov": hfov,
              "image_size": image_size}
    if camera is not None:
        given = tuple(name for name, value in placed.items() if value is not None)
        if given:
            raise InputError(f"give a camera file or {', '.join(given)}, not both", arguments=("camera", *given))
        return read_camera(camera)
    try:
        size = default_image_size if image_size is None else parse_image_size(image_size, "image_size")
    except InputError as err:
        raise InputError(err.message, ("image_size",)) from None
    if camera_height is None or pitch is None or size is None or (focal is None and hfov is None):
        raise InputError("no camera: give a camera file, or camera_height, pitch, image_size and hfov or focal",
                         arguments=("camera", "camera_height", "pitch", "image_size", "hfov"))
    return Camera.from_height_pitch(camera_height, pitch, size, roll or 0.0, focal, hfov)


@reads_file("floor file")
def read_floor(path: str | Path) -> Floor:
    """The floor regions a JSON file declares under ``"floor_regions"`` (a camera file of ours may carry them
    beside the camera, or a file may hold them alone): a list of ``{"name", "polygon": [[x, y], ...],
    "height_m"}`` (a flat region: a stage, a platform, a step) or ``{"name", "polygon", "vertex_heights_m": [...]}``
    (a plane through its vertices: a ramp, a flight of stairs as the plane through the middles of its treads), world
    metres. Where regions overlap the first listed decides; outside every region the floor is z = 0."""
    path = Path(path)
    document = read_json(path)
    check_camera_document(document, path)
    entries = document.get(FLOOR_KEY) if isinstance(document, dict) else None
    if not isinstance(entries, list) or not entries:
        raise InputError(f"{path}: {FLOOR_KEY}: expected a list of regions "
                         '({"name", "polygon": [[x, y], ...], "height_m" or "vertex_heights_m"})')
    regions = []
    for i, entry in enumerate(entries):
        where = f"{path}: {FLOOR_KEY}[{i}]"
        if not isinstance(entry, dict):
            raise InputError(f"{where}: expected an object, got {type(entry).__name__}")
        unknown = set(entry) - {"name", "polygon", "height_m", "vertex_heights_m"}
        if unknown:
            raise InputError(f"{where}: unknown field {sorted(unknown)[0]!r}")
        name = str(entry.get("name", f"region {i}"))
        polygon = numeric_array(entry.get("polygon"), f"{where}.polygon")
        if polygon.ndim != 2 or polygon.shape[1:] != (2,) or len(polygon) < 3:
            raise InputError(f"{where}.polygon: expected 3 or more [x, y] points in metres, got shape {polygon.shape}")
        if ("height_m" in entry) == ("vertex_heights_m" in entry):
            raise InputError(f"{where}: give exactly one of height_m (flat) and vertex_heights_m (a plane)")
        if "height_m" in entry:
            height = numeric_array(entry["height_m"], f"{where}.height_m")
            if height.ndim != 0:
                raise InputError(f"{where}.height_m: expected one number (metres)")
            heights = np.full(len(polygon), float(height))
        else:
            heights = numeric_array(entry["vertex_heights_m"], f"{where}.vertex_heights_m")
        try:
            regions.append(FloorRegion.from_vertex_heights(name, polygon, heights))
        except InputError as err:
            raise InputError(f"{where}: {err.message}") from None
    return Floor(tuple(regions))


def floor_of_camera_file(camera: str | Path | None) -> Floor:
    """The floor a camera file declares (``read_floor``), or the plain floor z = 0 when it declares none (or the
    camera is not a JSON file)."""
    return read_floor(camera) if FLOOR_KEY in _our_camera_document(camera) else FLAT_FLOOR


def floor_z_of_camera_file(camera: str | Path | None) -> float | None:
    """Where a camera file of ours says the floor people stand on lies in its frame (``"floor_z_m"``: a
    calibration whose z = 0 is a board on a table says -0.75), None when it does not say (then it is observed
    from the people: ``ray3d.refine.ankle_plane``)."""
    document = _our_camera_document(camera)
    return checked_floor_z(document[FLOOR_Z_KEY], f"{camera}: {FLOOR_Z_KEY}", ()) if FLOOR_Z_KEY in document else None


def save_camera_with_floor_z(camera: str | Path, out: str | Path, floor_z_m: float, overwrite: bool = False,
                             **info: Any) -> Path:
    """The camera file ``camera`` written to ``out`` with ``"floor_z_m"`` set (and any extra top-level ``info``),
    atomically; ``out`` may not be ``camera`` itself. A JSON file of ours keeps every other key as it was (its
    floor regions, how it was made); any other camera (OpenCV's, a calibration TOML's, ``h36m:...``) is written
    in ours (``save_cameras``)."""
    floor_z_m = checked_floor_z(floor_z_m, "floor_z_m", ("floor_z_m",))
    check_output(out, (camera,))
    document = _our_camera_document(camera)
    if not document or "camera_matrix" in document:  # not ours: the camera as we write cameras
        save_cameras(out, [read_camera(camera)], overwrite, **info, **{FLOOR_Z_KEY: round(floor_z_m, 4)})
        return Path(out)
    read_camera(camera)  # what is written must read back as a camera
    with atomic_path(out, overwrite) as temporary:
        temporary.write_text(json.dumps({**document, **info, FLOOR_Z_KEY: round(floor_z_m, 4)}, indent=1))
    return Path(out)


def _our_camera_document(camera: str | Path | None) -> dict:
    """A camera file of ours (JSON) as read, for what it declares beside the camera; {} for anything else."""
    if camera is None or not str(camera).lower().endswith(".json") or not Path(camera).is_file():
        return {}
    document = read_json(Path(camera))
    return document if isinstance(document, dict) else {}
