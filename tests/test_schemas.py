"""The JSON schemas shipped for every JSON file ray3d reads (``assets/*.schema.json``: world, site, camera and
floor, batch manifest, our keypoints, OpenCV's JSON camera, checkpoint configurations, other tools' keypoint
results lists and OpenPose frames): each is a valid schema, accepts what the reader reads and refuses, as the
reader does, the wrong shapes; the manifest's schema names exactly the columns the reader knows, the checkpoint's
exactly the model's fields and choices."""

from __future__ import annotations

import json
from importlib import resources

import cv2
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


@pytest.mark.parametrize("name", ["world", "site", "camera", "manifest", "keypoints", "opencv_camera", "checkpoint",
                                  "results_list", "openpose"])
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
    assert (len(read_floor(tmp_path / "floor.json").regions) == 2
            and len(read_floor(tmp_path / "single.json").regions) == 2)
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
                               [{**row, "precision": "fp8"}], [{**row, "every": "soon"}],
                               [{**row, "flip_test": "perhaps"}], {"inputs": [row], "extra": 1}, [],
                               [{**row, "image_size": "wide"}]]):
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


def _held_to(validator, reader, good: list, wrong: list, folder, suffix: str = ".json") -> None:
    """Each of ``good`` validates and ``reader`` reads it from a file; each of ``wrong`` fails validation and the
    reader refuses it (``InputError``)."""
    for k, document in enumerate(good):
        validator.validate(document)
        (folder / f"good{k}{suffix}").write_text(json.dumps(document))
        reader(folder / f"good{k}{suffix}")
    for k, document in enumerate(wrong):
        assert not validator.is_valid(document), k
        (folder / f"wrong{k}{suffix}").write_text(json.dumps(document))
        with pytest.raises(InputError):
            reader(folder / f"wrong{k}{suffix}")


def test_the_opencv_camera_schema_accepts_what_the_reader_reads_and_refuses_what_it_refuses(tmp_path):
    camera = cameras.h36m("S9", "54138969")
    K = camera.K.tolist()
    flat = {"camera_matrix": sum(K, []), "dist_coeffs": camera.dist.tolist(), "R": sum(camera.R.tolist(), []),
            "t": camera.t.tolist(), "image_width": 1000, "image_height": 1002}
    stored = {"camera_matrix": {"rows": 3, "cols": 3, "dt": "d", "data": sum(K, [])},
              "distortion_coefficients": {"rows": 1, "cols": 5, "dt": "d", "data": camera.dist.tolist()},
              "rvec": cv2.Rodrigues(camera.R)[0].ravel().tolist(), "tvec": camera.t.reshape(3, 1).tolist(),
              "width": 1000.0, "height": 1002}
    nested = {**flat, "camera_matrix": K, "R": camera.R.tolist()}
    wrong = [{**flat, "camera_matrix": sum(K, [])[:8]}, {**stored, "rvec": [0.1, 0.2]},
             {**stored, "camera_matrix": {"rows": 3, "cols": 3, "data": "abc"}}, {**flat, "image_width": "wide"},
             {**flat, "image_width": ""}, {**flat, "R": []}, {k: v for k, v in flat.items() if k != "t"},
             {k: v for k, v in flat.items() if k != "image_height"}, {**flat, "image_width": 0}]
    _held_to(_validator("opencv_camera"), read_camera, [flat, stored, nested], wrong, tmp_path)


def test_the_checkpoint_schema_holds_every_shipped_model_and_the_models_fields_and_choices():
    import dataclasses

    from ray3d.checkpoints import model_config, resolve, shipped_models
    from ray3d.models.network import BACKBONES, INPUTS, ROOTS, ModelConfig
    from ray3d.refine.config import UNCERTAINTY_FIELDS, model_uncertainty
    from ray3d.skeleton import LAYOUTS

    validator = _validator("checkpoint")
    model = validator.schema["properties"]["model"]["properties"]
    assert set(model) == {f.name for f in dataclasses.fields(ModelConfig)}
    assert set(validator.schema["properties"]["uncertainty"]["properties"]) == set(UNCERTAINTY_FIELDS)
    for field, choices in (("input", INPUTS), ("backbone", BACKBONES), ("root", ROOTS), ("layout", tuple(LAYOUTS))):
        assert set(model[field]["enum"]) == set(choices), field
    for name in shipped_models():
        document = json.loads(resolve(name).with_suffix(".json").read_text())
        validator.validate(document)
        model_config(document), model_uncertainty(document)
    document = json.loads(resolve("ray3d-real").with_suffix(".json").read_text())
    for k, wrong in enumerate([{**document, "model": "abc"}, {**document, "model": {**document["model"], "colour": 1}},
                               {**document, "model": {**document["model"], "backbone": "transformer-xl"}},
                               {**document, "uncertainty": "abc"}, {**document, "uncertainty": {"depth_sd": [0.1]}},
                               {**document, "uncertainty": {"floor_offset_sd_m": -1}}]):
        assert not validator.is_valid(wrong), k
        with pytest.raises(InputError):
            model_config(wrong), model_uncertainty(wrong)


def test_the_results_list_schema_accepts_coco_alphapose_and_mmpose_and_refuses_what_the_reader_refuses(tmp_path):
    pixels = cameras.h36m("S9", "54138969").project(demo_clip()[:3])[:, :, :2]
    flat = [[float(v) for joint in frame for v in (*joint, 0.9)] for frame in pixels]
    coco = [{"image_id": f, "category_id": 1, "keypoints": flat[f], "score": 0.9} for f in range(3)]
    alphapose = [{"image_id": f"frame_{f:04d}.jpg", "idx": [1.0], "keypoints": flat[f], "score": 2.1}
                 for f in range(3)]
    mmpose = [{"frame_id": f, "instances": [{"keypoints": pixels[f].tolist(), "keypoint_scores": [0.9] * 17,
                                             "track_id": 4}]} for f in range(3)]
    wrong = [[{"image_id": 0}], [{"image_id": 0, "keypoints": "abc"}], [],
             [{**coco[0], "track_id": {"a": 1}}], [{"frame_id": 0, "instances": "none"}]]
    _held_to(_validator("results_list"), lambda path: read_keypoints(path, layout="h36m17"), [coco, alphapose, mmpose],
             wrong, tmp_path)


def test_the_openpose_schema_accepts_a_frame_the_reader_reads_and_refuses_what_it_refuses(tmp_path):
    validator = _validator("openpose")
    person = {"person_id": [-1], "pose_keypoints_2d": [100.0, 200.0, 0.9] * 25, "face_keypoints_2d": []}
    for k, (document, good) in enumerate([({"version": 1.3, "people": [person, {**person, "person_id": 2}]}, True),
                                          ({"people": "none"}, False), ({"people": [3]}, False),
                                          ({"people": [{**person, "pose_keypoints_2d": [1.0, 2.0, 3.0]}]}, False),
                                          ({"people": [{**person, "person_id": {"a": 1}}]}, False)]):
        folder = tmp_path / str(k)
        folder.mkdir()
        (folder / "clip_000000000000_keypoints.json").write_text(json.dumps(document))
        assert validator.is_valid(document) == good, k
        if good:
            assert len(read_keypoints(folder).frames) == 2
        else:
            with pytest.raises(InputError):
                read_keypoints(folder)
