"""The JSON schemas shipped for every JSON file ray3d reads (``assets/*.schema.json``: world, site, camera and
floor, batch manifest): each is a valid schema, accepts what the reader reads and refuses, as the reader does, the
wrong shapes; the manifest's schema names exactly the columns the reader knows."""

from __future__ import annotations

import json
from importlib import resources

import numpy as np
import pytest

from ray3d import InputError, cameras
from ray3d.batch import read_manifest
from ray3d.batch.manifest import COLUMNS
from ray3d.demo import demo_clip
from ray3d.io.camera_files import read_camera, read_floor, save_cameras
from ray3d.io.keypoints import Keypoints, read_keypoints, write_keypoints_json

jsonschema = pytest.importorskip("jsonschema")


def _validator(name: str):
    schema = json.loads(resources.files("ray3d").joinpath("assets", f"{name}.schema.json").read_text())
    jsonschema.Draft202012Validator.check_schema(schema)
    return jsonschema.Draft202012Validator(schema)


@pytest.mark.parametrize("name", ["world", "site", "camera", "manifest", "keypoints"])
def test_every_shipped_schema_is_a_valid_draft_2020_12_schema(name):
    _validator(name)


FLOOR = [{"name": "stage", "polygon": [[0, 0], [2, 0], [2, 2]], "height_m": 0.3},
         {"name": "ramp", "polygon": [[3, 0], [5, 0], [5, 2]], "vertex_heights_m": [0, 0.2, 0.2]}]


def test_the_camera_schema_accepts_what_ray3d_writes_and_reads_and_refuses_what_it_refuses(tmp_path):
    validator = _validator("camera")
    camera = cameras.h36m("S9", "54138969")
    save_cameras(tmp_path / "list.json", [camera, camera], set="test")
    single = {**camera.to_dict(), "floor_regions": FLOOR}
    (tmp_path / "single.json").write_text(json.dumps(single))
    (tmp_path / "floor.json").write_text(json.dumps({"floor_regions": FLOOR}))
    for path in ("list.json", "single.json"):
        validator.validate(json.loads((tmp_path / path).read_text()))
        read_camera(tmp_path / path)
    validator.validate({"floor_regions": FLOOR})
    assert len(read_floor(tmp_path / "floor.json").regions) == 2 and len(read_floor(tmp_path / "single.json").regions) == 2
    good = camera.to_dict()
    wrong_cameras = [{k: v for k, v in good.items() if k != "fx"}, {**good, "R": good["R"][:2]},
                     {**good, "t": [0, 0]}, {**good, "dist": [0, 0, 0]}, {"cameras": []}]
    for k, wrong in enumerate(wrong_cameras):
        assert not validator.is_valid(wrong), k
        (tmp_path / f"wrong{k}.json").write_text(json.dumps(wrong))
        with pytest.raises(InputError):
            read_camera(tmp_path / f"wrong{k}.json")
    wrong_floors = [[{"polygon": [[0, 0], [1, 0]], "height_m": 0.1}],
                    [{"polygon": [[0, 0], [1, 0], [1, 1]], "height_m": 0.1, "vertex_heights_m": [0, 0, 0]}],
                    [{"polygon": [[0, 0], [1, 0], [1, 1]]}], [{"polygon": [[0, 0], [1, 0], [1, 1]], "height_m": 0.1,
                                                              "slope": 3}]]
    for k, regions in enumerate(wrong_floors):
        assert not validator.is_valid({"floor_regions": regions}), k
        (tmp_path / f"floor{k}.json").write_text(json.dumps({"floor_regions": regions}))
        with pytest.raises(InputError):
            read_floor(tmp_path / f"floor{k}.json")


def test_the_manifest_schema_names_the_readers_columns_and_refuses_what_it_refuses(tmp_path):
    validator = _validator("manifest")
    assert set(validator.schema["$defs"]["row"]["properties"]) == set(COLUMNS)
    np.savez(tmp_path / "take.npz", keypoints=cameras.h36m("S9", "54138969").project(demo_clip()[:20]), fps=50.0)
    rows = [{"input": "take.npz", "camera": "h36m:S9:54138969", "fps": 50, "flip_test": True, "every": "15min",
             "smooth_3d": "none", "frame": "camera"},
            {"input": "take.npz", "name": "second", "camera_height": "3", "pitch": 20, "hfov": 60,
             "image_size": "1000x1000", "precision": "bf16", "camera_index": 0}]
    for document in (rows, {"inputs": rows}):
        validator.validate(document)
        (tmp_path / "m.json").write_text(json.dumps(document))
        assert len(read_manifest(tmp_path / "m.json")) == 2
    row = rows[0]
    for k, wrong in enumerate([[{**row, "colour": "red"}], [{k: v for k, v in row.items() if k != "input"}],
                               [{**row, "precision": "fp8"}], [{**row, "every": "soon"}], [{**row, "flip_test": "perhaps"}],
                               {"inputs": [row], "extra": 1}, [], [{**row, "image_size": "wide"}]]):
        assert not validator.is_valid(wrong), k
        (tmp_path / f"wrong{k}.json").write_text(json.dumps(wrong))
        with pytest.raises(InputError):
            read_manifest(tmp_path / f"wrong{k}.json")


def test_the_keypoints_schema_accepts_what_ray3d_writes_and_refuses_what_its_reader_refuses(tmp_path):
    validator = _validator("keypoints")
    pixels = cameras.h36m("S9", "54138969").project(demo_clip()[:6])
    keypoints = Keypoints(pixels, np.ones(pixels.shape[:2]), np.arange(6), np.array(["a", "a", "a", "b", "b", "b"]),
                          "h36m17", 50.0, "test")
    write_keypoints_json(tmp_path / "k.json", keypoints)
    validator.validate(json.loads((tmp_path / "k.json").read_text()))
    assert read_keypoints(tmp_path / "k.json").layout == "h36m17"
    good = json.loads((tmp_path / "k.json").read_text())
    detection = good["detections"][0]
    for k, wrong in enumerate([{**good, "detections": []}, {**good, "detections": [{"frame": 0, "track": 1}]},
                               {**good, "detections": [{**detection, "keypoints": [[1.0]] * 17}]},
                               {**good, "detections": [{**detection, "keypoints": [[1.0, 2.0, 3.0, 4.0]] * 17}]}]):
        assert not validator.is_valid(wrong), k
        (tmp_path / f"wrong{k}.json").write_text(json.dumps(wrong))
        with pytest.raises(InputError):
            read_keypoints(tmp_path / f"wrong{k}.json")
