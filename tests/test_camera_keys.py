"""Strict camera files (issue 68): every key a camera file of ours may carry is known to the reader and to
``assets/camera.schema.json`` alike; a file ray3d wrote always reads back, and a misspelt key (``"dsit"``,
``"floor_zm"``, ``"heigth"``) is refused in one line naming the file, the key and the key it most likely meant,
through the library and the command line (exit 2)."""

from __future__ import annotations

import json
from importlib import resources

import numpy as np
import pytest

from ray3d import InputError, cameras
from ray3d.calibrate import FloorCheck, PersonCalibration
from ray3d.cli import main
from ray3d.demo import demo_clip
from ray3d.io.camera_files import read_camera, read_floor, save_camera_with_floor_z, save_cameras
from ray3d.io.camera_keys import CAMERA_KEYS, FILE_KEYS, LIST_INFO_KEYS, SINGLE_INFO_KEYS

CAMERA = cameras.h36m("S9", "54138969")
FLOOR = [{"name": "stage", "polygon": [[0, 0], [2, 0], [2, 2]], "height_m": 0.3}]


def _schema() -> dict:
    return json.loads(resources.files("ray3d").joinpath("assets", "camera.schema.json").read_text())


def _validator():
    jsonschema = pytest.importorskip("jsonschema")
    schema = _schema()
    jsonschema.Draft202012Validator.check_schema(schema)
    return jsonschema.Draft202012Validator(schema)


def _write(folder, name: str, document: dict):
    path = folder / name
    path.write_text(json.dumps(document))
    return path


def test_the_schema_and_the_reader_know_the_same_keys():
    schema = _schema()
    single, listed, floor_only = schema["oneOf"]
    assert set(schema["$defs"]["camera_fields"]["properties"]) == set(CAMERA_KEYS)
    assert set(schema["$defs"]["camera_fields"]["required"]) == set(CAMERA_KEYS) - {"name"}
    assert set(single["properties"]) == {*FILE_KEYS, *SINGLE_INFO_KEYS}
    assert set(listed["properties"]) == {"cameras", *FILE_KEYS, *LIST_INFO_KEYS}
    assert set(floor_only["properties"]) == {"floor_regions", "name", "description"}
    # what ray3d calibrate --from-person writes beside its camera is all known
    person = PersonCalibration(CAMERA, 0.1, 1.0, 1.0, 20.0, 2.0, 100, 2, ("few frames",))
    assert set(person.to_dict()) <= set(LIST_INFO_KEYS)


def test_every_camera_file_ray3d_writes_reads_back_and_validates(tmp_path):
    validator = _validator()
    person = PersonCalibration(CAMERA, 0.1, 1.0, 1.0, 20.0, 2.0, 100, 2, ("few frames",))
    check = FloorCheck(-0.74, 0.02, "lens height", lens_height_m=2.1)
    written = {
        "cameras.json": dict(set="extrinsic-test", filter="kept cameras that see every joint"),  # ray3d cameras
        "floor-points.json": dict(reprojection_rms_px=0.8),                                     # --floor-points
        "person.json": dict(calibration="from person", person_height_m=1.7, tracks=["1", "2"],  # --from-person
                            **person.to_dict()),
    }
    for name, info in written.items():
        save_cameras(tmp_path / name, [CAMERA, CAMERA], **info)
    _write(tmp_path, "single.json", {**CAMERA.to_dict(), "floor_regions": FLOOR,
                                    "description": "a board on a table", "_note": "a comment"})
    for source in ("person.json", "single.json"):  # ray3d calibrate --floor-of, on a list and on one camera
        save_camera_with_floor_z(tmp_path / source, tmp_path / f"floor-{source}", check.floor_z_m,
                                 floor_check=check.to_dict())
    written_names = [*written, "single.json", "floor-person.json", "floor-single.json"]
    for name in written_names:
        document = json.loads((tmp_path / name).read_text())
        validator.validate(document)
        assert np.allclose(read_camera(tmp_path / name).K, CAMERA.K), name
    assert json.loads((tmp_path / "floor-single.json").read_text())["floor_check"]["how"] == "lens height"
    assert len(read_floor(tmp_path / "floor-single.json").regions) == 1
    validator.validate({"floor_regions": FLOOR, "name": "stage", "_why": "the band"})
    assert len(read_floor(_write(tmp_path, "floor.json", {"floor_regions": FLOOR, "name": "stage"})).regions) == 1


def _without(key: str) -> dict:
    return {k: v for k, v in CAMERA.to_dict().items() if k != key}


# (the document, what the message must hold)
TYPOS = {
    "dsit": ({**_without("dist"), "dsit": [0.1, 0, 0, 0, 0]}, ("missing field dist", "'dsit'", "'dist'")),
    "floor_zm": ({**CAMERA.to_dict(), "floor_zm": -0.5}, ("'floor_zm'", "did you mean 'floor_z_m'")),
    "heigth": ({**_without("height"), "heigth": 1000}, ("missing field height", "'heigth'", "'height'")),
    "case": ({**_without("R"), "r": CAMERA.R.tolist()}, ("missing field R", "'r'")),
    "list floor_zm": ({"cameras": [CAMERA.to_dict()], "floor_zm": -0.5}, ("'floor_zm'", "'floor_z_m'")),
    "list floor_chek": ({"cameras": [CAMERA.to_dict()], "floor_chek": {}}, ("'floor_chek'", "'floor_check'")),
    "list entry dsit": ({"cameras": [CAMERA.to_dict(), {**_without("dist"), "dsit": [0] * 5}]},
                        ("camera 1", "'dsit'", "'dist'")),
    "floor in an entry": ({"cameras": [{**CAMERA.to_dict(), "floor_z_m": -0.5}]},
                          ("camera 0", "'floor_z_m'", "top level")),
    "unknown": ({**CAMERA.to_dict(), "colour": "red"}, ("'colour'", "fx, fy")),
}


@pytest.mark.parametrize("case", TYPOS)
def test_a_misspelt_key_is_refused_naming_it_and_the_key_it_meant(case, tmp_path):
    document, needles = TYPOS[case]
    path = _write(tmp_path, "typo.json", document)
    with pytest.raises(InputError) as caught:
        read_camera(path)
    message = str(caught.value)
    assert str(path) in message and "\n" not in message, message
    for needle in needles:
        assert needle in message, message
    assert not _validator().is_valid(document), case


def test_floor_files_and_opencv_cameras_catch_their_typos_too(tmp_path):
    with pytest.raises(InputError, match="'floor_region'.*did you mean 'floor_regions'"):
        read_floor(_write(tmp_path, "floor.json", {"floor_region": FLOOR}))
    with pytest.raises(InputError, match="'floor_z_m'"):  # a floor file says no floor height: a camera file does
        read_floor(_write(tmp_path, "floor2.json", {"floor_regions": FLOOR, "floor_z_m": 0.1}))
    opencv = {"camera_matrix": CAMERA.K.ravel().tolist(), "R": CAMERA.R.ravel().tolist(), "t": CAMERA.t.tolist(),
              "image_width": 1000, "image_height": 1002}
    with pytest.raises(InputError, match="'dist_coefs'.*did you mean 'dist_coeffs'"):
        read_camera(_write(tmp_path, "cv.json", {**opencv, "dist_coefs": [0.1, 0, 0, 0, 0]}))
    # other tools write more than we read: what is not a near miss of a missing field passes
    read_camera(_write(tmp_path, "cv2.json", {**opencv, "dist_coeffs": [0.0] * 5, "rvecs": [[0, 0, 0]],
                                              "avg_reprojection_error": 0.3, "board_width": 9}))


@pytest.mark.parametrize("case", ["dsit", "floor_zm"])
def test_the_command_line_refuses_a_misspelt_camera_file_in_one_line(case, tmp_path, capsys):
    document, needles = TYPOS[case]
    camera = _write(tmp_path, "camera.json", document)
    np.savez(tmp_path / "k.npz", keypoints=CAMERA.project(demo_clip()[:12]))
    capsys.readouterr()
    code = main(["lift", "--keypoints", str(tmp_path / "k.npz"), "--camera", str(camera), "--out",
                 str(tmp_path / "out.json")])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1, err
    for needle in ("camera.json", *needles):
        assert needle in err, err
    assert not (tmp_path / "out.json").exists()

