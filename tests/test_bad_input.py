"""Bad input through the command line and the readers: one line naming the file or field, exit code 2, no
traceback, nothing the user had changed; anything unexpected is one line and exit code 1. Fuzzed files reach
the readers and end as ``InputError`` or a result, never another exception."""

from __future__ import annotations

import json
import os
import re
import stat
import subprocess
import sys
import zipfile

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import ray3d
from ray3d import InputError, cameras
from ray3d.cli import main
from ray3d.demo import demo_clip
from ray3d.io.camera_files import read_camera
from ray3d.io.keypoints import read_keypoints
from ray3d.io.world import read_world

CAMERA = "h36m:S9:54138969"


@pytest.fixture()
def keypoints_file(tmp_path):
    path = tmp_path / "k.npz"
    np.savez(path, keypoints=cameras.h36m("S9", "54138969").project(demo_clip()[:20]))
    return path


def _fails_cleanly(capsys, argv, *needles):
    """Runs the CLI; asserts exit code 2 and one line on stderr holding every needle."""
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    for needle in needles:
        assert needle in err, err
    return err


def _lift(keypoints, out, *extra, camera=CAMERA):
    return ["lift", "--keypoints", str(keypoints), "--camera", str(camera), "--out", str(out), *extra]


CAMERA_FILES = {
    "negative.yaml": ("%YAML:1.0\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   cols: -1\n   dt: d\n"
                      "   data: [1, 0, 0]\n", "camera_matrix.cols: expected a whole number 1-16, got -1"),
    "huge.yaml": ("%YAML:1.0\ncamera_matrix: !!opencv-matrix\n   rows: 100000\n   cols: 100000\n   dt: d\n"
                  "   data: [1]\n", "camera_matrix.rows: expected a whole number 1-16, got 100000"),
    "empty.yaml": ("", "empty file"),
    "bigint.json": ('{"fx": 1' + "0" * 400 + ', "fy": 1, "cx": 1, "cy": 1, "R": [[1,0,0],[0,1,0],[0,0,1]], '
                    '"t": [0,0,0], "image_size": [10, 10]}', "bigint.json"),
    "list.json": ("[]", "list.json"),
    "text.json": ('"camera"', "text.json"),
}


@pytest.mark.parametrize("name", sorted(CAMERA_FILES))
def test_bad_camera_files_end_in_one_line(name, tmp_path, keypoints_file, capsys):
    text, needle = CAMERA_FILES[name]
    camera = tmp_path / name
    camera.write_text(text)
    _fails_cleanly(capsys, _lift(keypoints_file, tmp_path / "out.json", camera=camera), needle)
    assert not (tmp_path / "out.json").exists()


def test_a_negative_opencv_matrix_size_cannot_abort_the_process(tmp_path):
    """OpenCV's own reader aborts on it (ray3d parses the file itself): checked in a child process, so a regression
    cannot take pytest down."""
    camera = tmp_path / "negative.yaml"
    camera.write_text(CAMERA_FILES["negative.yaml"][0])
    code = (f"from ray3d.io.camera_files import read_camera\ntry:\n read_camera({str(camera)!r})\n"
            "except ValueError as e:\n print(e)")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0 and "expected a whole number 1-16, got -1" in run.stdout


KEYPOINT_FILES = {
    "empty-list.json": ("[]", "k"),
    "null.json": ("null", "k"),
    "deep.json": ("[" * 5000 + "]" * 5000, "deep.json"),
    "fewer-fields.csv": ("frame,joint,x,y\n0,0,1,2\n0,1,3\n", "fewer-fields.csv"),
    "fps-zero.json": (json.dumps({"fps": 0, "layout": "h36m17", "detections": [
        {"frame": 0, "keypoints": [[1.0, 2.0]] * 17}]}), "fps must be a positive number"),
    "duplicate-frames.json": (json.dumps({"layout": "h36m17", "detections": [
        {"frame": 3, "keypoints": [[1.0, 2.0]] * 17}] * 30}), "same frame appears more than once"),
    "absurd-frames.json": (json.dumps({"layout": "h36m17", "detections": [
        {"frame": 0, "keypoints": [[1.0, 2.0]] * 17}, {"frame": 10 ** 12, "keypoints": [[1.0, 2.0]] * 17}]}),
        "span at most"),
}


@pytest.mark.parametrize("name", sorted(KEYPOINT_FILES))
def test_bad_keypoint_files_end_in_one_line(name, tmp_path, capsys):
    text, needle = KEYPOINT_FILES[name]
    keypoints = tmp_path / name
    keypoints.write_text(text)
    _fails_cleanly(capsys, _lift(keypoints, tmp_path / "out.json"), needle)


def test_a_corrupted_npz_ends_in_one_line(tmp_path, keypoints_file, capsys):
    data = bytearray(keypoints_file.read_bytes())
    data[len(data) // 2] ^= 0xFF
    broken = tmp_path / "broken.npz"
    broken.write_bytes(bytes(data))
    _fails_cleanly(capsys, _lift(broken, tmp_path / "out.json"), "broken.npz")


@pytest.mark.parametrize("flags, needle", [
    (["--camera-height", "3", "--pitch", "95", "--hfov", "60", "--image-size", "1000x1000"], "(--pitch)"),
    (["--camera-height", "-1", "--pitch", "10", "--hfov", "60", "--image-size", "1000x1000"], "(--camera-height)"),
    (["--camera", CAMERA, "--fps", "0"], "(--fps)"),
    (["--camera", CAMERA, "--fps", "nan"], "(--fps)"),
    (["--camera", CAMERA, "--checkpoint", "rfrh"], "no-learning baseline"),
    (["--camera", CAMERA, "--layout", "coco"], "unknown joint layout 'coco'"),
])
def test_impossible_cameras_rates_and_models_are_refused(flags, needle, tmp_path, keypoints_file, capsys):
    _fails_cleanly(capsys, ["lift", "--keypoints", str(keypoints_file), "--out", str(tmp_path / "o.json"), *flags],
                   needle)
    assert not (tmp_path / "o.json").exists()


def test_an_output_that_is_an_input_or_a_folder_is_refused_before_any_work(tmp_path, keypoints_file, capsys):
    before = keypoints_file.read_bytes()
    _fails_cleanly(capsys, _lift(keypoints_file, keypoints_file, "--force"), "is also an input")
    assert keypoints_file.read_bytes() == before
    (tmp_path / "folder").mkdir()
    _fails_cleanly(capsys, _lift(keypoints_file, tmp_path / "folder", "--force"), "is a folder")
    _fails_cleanly(capsys, _lift(keypoints_file, keypoints_file / "inside.json"), "is a file, not a folder")
    world = tmp_path / "w.json"
    assert main(_lift(keypoints_file, world)) == 0
    capsys.readouterr()
    _fails_cleanly(capsys, ["viz", str(world), "--html", str(world), "--force"], "is also an input")
    assert read_world(world).tracks


def test_export_onnx_without_the_extra_says_what_to_install(tmp_path, monkeypatch, capsys):
    import importlib.util

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "onnx" else real(name, *a))
    _fails_cleanly(capsys, ["export", "--onnx", "--out", str(tmp_path / "m.onnx")], "pip install 'ray3d[onnx]'")


def test_an_internal_error_is_one_line_with_exit_code_1_and_a_traceback_only_with_debug(monkeypatch, capsys):
    from ray3d.cli import model_commands

    def broken(args):
        raise RuntimeError("something inside broke")

    monkeypatch.setattr(model_commands, "models", broken)
    assert main(["models"]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "internal error: RuntimeError: something inside broke" in err
    assert "--debug" in err
    with pytest.raises(RuntimeError):
        main(["--debug", "models"])


def test_written_files_follow_the_umask(tmp_path, keypoints_file):
    previous = os.umask(0o022)
    try:
        assert main(_lift(keypoints_file, tmp_path / "w.csv")) == 0
    finally:
        os.umask(previous)
    assert stat.S_IMODE((tmp_path / "w.csv").stat().st_mode) == 0o644


def test_the_package_reaches_calibration_and_the_file_readers():
    assert callable(ray3d.calibrate.from_person) and ray3d.read_camera is read_camera
    assert ray3d.read_camera(CAMERA).name


_FUZZ = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


def _only_input_errors(read, path):
    try:
        read(path)
    except InputError:
        pass


@_FUZZ
@given(data=st.binary(max_size=400), suffix=st.sampled_from([".json", ".csv", ".npz"]))
def test_fuzzed_keypoint_files_raise_only_input_errors(tmp_path_factory, data, suffix):
    path = tmp_path_factory.mktemp("fuzz") / f"k{suffix}"
    path.write_bytes(data)
    _only_input_errors(read_keypoints, path)


@_FUZZ
@given(document=st.recursive(st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=5),
                             lambda inner: st.lists(inner, max_size=4) | st.dictionaries(
                                 st.sampled_from(["fx", "fy", "cx", "cy", "R", "t", "dist", "image_size", "cameras",
                                                  "detections", "keypoints", "frame", "track", "fps", "layout",
                                                  "tracks", "joints", "camera", "units", "instances", "frame_id",
                                                  "image_id", "idx", "keypoint_scores", "score", "track_id",
                                                  "person_id"]), inner, max_size=6),
                             max_leaves=20))
def test_fuzzed_json_documents_raise_only_input_errors(tmp_path_factory, document):
    path = tmp_path_factory.mktemp("fuzz") / "doc.json"
    path.write_text(json.dumps(document))
    for read in (read_keypoints, read_camera, read_world):
        _only_input_errors(read, path)


@_FUZZ
@given(data=st.binary(max_size=300), name=st.sampled_from(["c.yaml", "c.xml"]))
def test_fuzzed_opencv_camera_files_raise_only_input_errors(tmp_path_factory, data, name):
    path = tmp_path_factory.mktemp("fuzz") / name
    path.write_bytes(b"%YAML:1.0\n" + data if name.endswith(".yaml") else data)
    _only_input_errors(read_camera, path)


def test_a_fuzzed_npz_member_raises_only_input_errors(tmp_path):
    path = tmp_path / "k.npz"
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("keypoints.npy", b"\x93NUMPY\x01\x00" + bytes(range(200)))
    with pytest.raises(InputError, match="k.npz"):
        read_keypoints(path)


@pytest.mark.parametrize("stride", ["0", "-3"])
def test_an_evaluation_stride_below_one_frame_is_refused(stride, capsys):
    _fails_cleanly(capsys, ["evaluate", "--checkpoint", "ray3d", "--cameras", "h36m", "--frame-stride", stride],
                   "(--frame-stride)")


_NUMBERS = st.lists(st.floats(allow_nan=True, allow_infinity=True) | st.integers(-5, 5) | st.text(max_size=3),
                    max_size=11)
_MATRIX = (_NUMBERS | st.lists(_NUMBERS, max_size=4)
           | st.fixed_dictionaries({"rows": st.integers(-2, 20) | st.text(max_size=2), "cols": st.integers(-2, 20),
                                    "data": _NUMBERS | st.text(max_size=4)}))
_SIDE = st.integers(-10, 5000) | st.floats() | st.text(max_size=4) | st.booleans() | st.none()


@_FUZZ
@given(fields=st.fixed_dictionaries({"camera_matrix": _MATRIX},
                                    optional={"dist_coeffs": _MATRIX, "rvec": _MATRIX, "tvec": _MATRIX, "R": _MATRIX,
                                              "t": _MATRIX, "image_width": _SIDE, "image_height": _SIDE}))
def test_opencv_json_cameras_of_any_shape_are_refused_in_one_line(tmp_path_factory, fields):
    """OpenCV's JSON camera form with fields of every wrong shape and type: a camera or one ``InputError``
    naming the file (structure checked before any reshape; issue 49)."""
    path = tmp_path_factory.mktemp("fuzz") / "c.json"
    path.write_text(json.dumps(fields))
    try:
        read_camera(path)
    except InputError as err:
        assert str(path) in str(err) or "camera" in str(err)


@pytest.mark.parametrize("fields, needle", [
    ({"camera_matrix": list(range(8))}, "camera_matrix: expected 9 numbers, got 8"),
    ({"rvec": [0, 0]}, "rvec: expected 3 numbers, got 2"),
    ({"camera_matrix": {"rows": 3, "cols": 3, "data": "abc"}},
     "camera_matrix.data: expected a list of numbers, got 'abc'"),
    ({"camera_matrix": {"rows": 3, "cols": 3, "data": [["a"] * 3] * 3}}, "camera_matrix.data: not numeric"),
    # issue 69: a null size or data that is no list is named, not a TypeError
    ({"camera_matrix": {"rows": None, "cols": 3, "data": list(range(9))}},
     "camera_matrix.rows: expected a whole number 1-16, got null"),
    ({"camera_matrix": {"rows": 3, "cols": None, "data": list(range(9))}},
     "camera_matrix.cols: expected a whole number 1-16, got null"),
    ({"camera_matrix": {"rows": 3, "cols": 3, "data": None}},
     "camera_matrix.data: expected a list of numbers, got null"),
    ({"camera_matrix": {"rows": 3, "cols": 3, "data": 5}}, "camera_matrix.data: expected a list of numbers, got 5"),
    ({"camera_matrix": {"rows": 3, "cols": 3, "data": {"0": 1}}}, "camera_matrix.data: expected a list of numbers"),
    ({"camera_matrix": {"rows": 3, "cols": 3}}, "camera_matrix: expected a list of numbers or OpenCV's"),
    ({"camera_matrix": None}, "camera_matrix: expected a list of numbers, got null"),
    ({"tvec": 5}, "tvec: expected a list of numbers, got 5"),
    ({"image_width": "wide"}, "image_width: expected a positive whole number"),
    ({"image_width": ""}, "image_width: expected a positive whole number"),
    ({"R": [], "t": []}, "R: expected 9 numbers, got 0"),
])
def test_the_issue_49_opencv_json_cameras_name_their_field(tmp_path, fields, needle):
    good = {"camera_matrix": [[1000, 0, 50], [0, 1000, 50], [0, 0, 1]], "rvec": [0.1, 0, 0], "tvec": [0, 0, 5],
            "image_width": 100, "image_height": 100}
    document = {**good, **fields}
    if "R" in fields:
        del document["rvec"], document["tvec"]
    path = tmp_path / "c.json"
    path.write_text(json.dumps(document))
    with pytest.raises(InputError, match=re.escape(needle)):
        read_camera(path)


def test_a_json_nested_deeper_than_python_can_parse_is_refused(tmp_path):
    path = tmp_path / "deep.json"
    path.write_text("[" * 100_000 + "]" * 100_000)
    for read in (read_camera, read_keypoints, read_world):
        with pytest.raises(InputError, match="nested too deeply"):
            read(path)


@pytest.mark.parametrize("change, needle", [
    (lambda d: d["model"].update(colour="red"), "model: unknown field 'colour'"),
    (lambda d: d.update(model="abc"), "model: expected an object of model fields, got str"),
    (lambda d: d["model"].update(channels=64), "does not fit its configuration"),
    (lambda d: d["model"].update(kernels=[3, 3, 3, 3, 3, 3]), "does not fit its configuration"),
    (lambda d: d["model"].update(backbone="transformer-xl"), "model: "),
    (lambda d: d.update(uncertainty="abc"), "uncertainty: expected an object, got str"),
    (lambda d: d.update(uncertainty={"depth_bias_sd": [[1, "x"]]}), "uncertainty: depth_bias_sd: not numeric"),
    (lambda d: d.update(uncertainty={"depth_sd": [0.1]}), "uncertainty: depth_sd: expected [a, b]"),
    (lambda d: d.update(uncertainty={"depth_bias_sd": [[5, 0.1], [2, 0.1]]}), "the distances must increase"),
    (lambda d: d.update(uncertainty={"floor_offset_sd_m": -1}), "floor_offset_sd_m: expected a number >= 0"),
])
def test_a_checkpoint_whose_json_does_not_fit_its_weights_is_refused_in_one_line(tmp_path, change, needle, capsys):
    """A checkpoint's configuration with an unknown key, a string for an object, or sizes that do not match
    the weights, or an uncertainty of the wrong shape: one line naming the JSON and what is wrong (issue 49),
    never a raw PyTorch size dump or an internal error when lifting."""
    from ray3d.checkpoints import load_model, resolve

    source = resolve("ray3d")
    document = json.loads(source.with_suffix(".json").read_text())
    change(document)
    (tmp_path / "m.json").write_text(json.dumps(document))
    (tmp_path / "m.safetensors").write_bytes(source.read_bytes())
    with pytest.raises(InputError, match=re.escape(needle)) as refused:
        load_model(tmp_path / "m.safetensors")
    assert str(tmp_path / "m.json") in str(refused.value) and "\n" not in str(refused.value)


@_FUZZ
@given(field=st.sampled_from(["depth_sd", "depth_bias_sd", "floor_offset_sd_m", "residual_distance_sd"]),
       value=st.recursive(st.none() | st.booleans() | st.floats() | st.integers() | st.text(max_size=3),
                          lambda inner: st.lists(inner, max_size=4), max_leaves=12))
def test_a_checkpoints_uncertainty_of_any_shape_is_read_or_refused_in_one_line(field, value):
    """Whatever a checkpoint's ``uncertainty`` holds: refused as ``InputError`` naming the field, or read into a
    refinement configuration whose error model gives finite sds."""
    from ray3d.refine.config import RefineConfig, model_uncertainty

    try:
        measured = model_uncertainty({"uncertainty": {field: value}})
    except InputError as err:
        assert f"uncertainty: {field}" in str(err) and "\n" not in str(err)
        return
    config = RefineConfig.for_model({"uncertainty": measured})
    assert np.isfinite(config.network_bias_sd(np.array([1.0, 10.0]))).all()
    assert np.isfinite(config.network_frame_sd(np.array([1.0, 10.0]))).all()


_JSON_VALUES = st.recursive(st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=5),
                            lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=3), inner,
                                                                                         max_size=3), max_leaves=10)


@_FUZZ
@given(section=st.sampled_from(["model", "uncertainty", None]),
       field=st.sampled_from(["name", "layout", "output_layout", "input", "backbone", "kernels", "root_kernels",
                              "channels", "layers", "hidden", "dropout", "causal", "depth_sd", "depth_bias_sd",
                              "floor_offset_sd_m", "model", "uncertainty", "colour"]), value=_JSON_VALUES)
def test_a_checkpoint_json_with_any_field_replaced_loads_or_is_refused_in_one_line(tmp_path_factory, section, field,
                                                                                   value):
    """A shipped checkpoint's JSON with any one field of its model, its uncertainty or its top level replaced by
    any JSON value: the model loads, or one ``InputError`` names the JSON; never an internal error."""
    from ray3d.checkpoints import load_model, resolve

    source = resolve("ray3d-real")
    document = json.loads(source.with_suffix(".json").read_text())
    (document if section is None else document[section])[field] = value
    folder = tmp_path_factory.mktemp("checkpoint")
    (folder / "m.json").write_text(json.dumps(document))
    os.link(source, folder / "m.safetensors")
    try:
        load_model(folder / "m.safetensors")
    except InputError as err:
        assert str(folder / "m.json") in str(err) and "\n" not in str(err)


@pytest.mark.parametrize("files, needle", [
    ({"a_keypoints.json": [1, 2]}, "people: expected a list of people"),
    ({"a_keypoints.json": {"people": [3]}}, "people: expected a list of people"),
    ({"a_keypoints.json": {"people": [{"pose_keypoints_2d": [1.0] * 75, "person_id": {"a": 1}}]}},
     "a track id (track_id, idx, person_id) must be a number or a name"),
])
def test_openpose_frames_of_the_wrong_shape_name_the_file_and_field(tmp_path, files, needle):
    for name, document in files.items():
        (tmp_path / name).write_text(json.dumps(document))
    with pytest.raises(InputError, match=re.escape(needle)) as refused:
        read_keypoints(tmp_path)
    assert str(tmp_path / "a_keypoints.json") in str(refused.value)


def _valid_files(folder) -> dict:
    """One valid file of each kind not fuzzed above, with its reader: site files (JSON, YAML), floor regions,
    batch manifests (CSV, JSON) and world files (JSON, CSV)."""
    from ray3d.batch import read_manifest
    from ray3d.io.camera_files import read_floor
    from ray3d.io.world import LiftResult, World, write_world
    from ray3d.site.files import read_site

    site = {"zones": [{"name": "room", "polygon": [[0, 0], [4, 0], [4, 3]], "max_occupancy": 2}],
            "lines": [{"name": "door", "start": [0, -1], "end": [0, 1]}]}
    (folder / "site.json").write_text(json.dumps(site))
    (folder / "site.yaml").write_text("zones:\n  - name: room\n    polygon: [[0, 0], [4, 0], [4, 3]]\n"
                                      "lines:\n  - {name: door, start: [0, -1], end: [0, 1]}\n")
    (folder / "floor.json").write_text(json.dumps({"floor_regions": [
        {"name": "stage", "polygon": [[0, 0], [2, 0], [2, 2]], "height_m": 0.3},
        {"name": "ramp", "polygon": [[3, 0], [5, 0], [5, 2]], "vertex_heights_m": [0, 0.2, 0.2]}]}))
    np.savez(folder / "take.npz", keypoints=cameras.h36m("S9", "54138969").project(demo_clip()[:20]), fps=50.0)
    (folder / "m.csv").write_text("input,camera,fps,flip_test\ntake.npz,h36m:S9:54138969,50,yes\n")
    (folder / "m.json").write_text(json.dumps({"inputs": [{"input": "take.npz", "camera_height": 3, "pitch": 20,
                                                           "hfov": 60, "image_size": "1000x1000"}]}))
    joints = np.zeros((4, 17, 3)) + [0.0, 0.0, 0.9]
    world = World({"1": LiftResult(joints, np.zeros((4, 17), bool), 10.0, np.arange(4))},
                  cameras.h36m("S9", "54138969"), "ray3d", rejoined={"1": [{"joined": "2", "after_frame": 1,
                                                                               "gap_s": 0.5}]})
    for suffix in (".json", ".csv"):
        write_world(folder / f"world{suffix}", world)
    return {"site.json": read_site, "site.yaml": read_site, "floor.json": read_floor, "m.csv": read_manifest,
            "m.json": read_manifest, "world.json": read_world, "world.csv": read_world}


@_FUZZ
@given(name=st.sampled_from(["site.json", "site.yaml", "floor.json", "m.csv", "m.json", "world.json", "world.csv"]),
       edits=st.lists(st.tuples(st.floats(0, 1), st.integers(0, 8), st.binary(max_size=6)), min_size=1, max_size=4))
def test_valid_files_of_every_kind_mutated_raise_only_input_errors(tmp_path_factory, name, edits):
    """A valid site, floor, batch manifest or world file with bytes cut, replaced or inserted at random is read or
    refused as ``InputError``, never anything else."""
    folder = tmp_path_factory.mktemp("mutated")
    readers = _valid_files(folder)
    data = bytearray((folder / name).read_bytes())
    for where, cut, inserted in edits:
        at = int(where * len(data))
        data[at:at + cut] = inserted
    (folder / name).write_bytes(bytes(data))
    _only_input_errors(readers[name], folder / name)


def test_paths_the_system_refuses_and_numbers_beyond_any_float_are_one_line(tmp_path, keypoints_file, capsys):
    """Found by the reader fuzz: a path too long to look up (a command's argument, a manifest's column) and an
    OpenCV JSON image width of 10^400 are refused in one line, never an internal error."""
    from ray3d.batch import read_manifest

    too_long = "a" * 5000
    assert main(["lift", "--keypoints", str(keypoints_file), "--camera", too_long, "--out",
                 str(tmp_path / "w.json")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "error:" in err[0] and "internal" not in err[0]
    (tmp_path / "take.npz").write_bytes(keypoints_file.read_bytes())
    (tmp_path / "m.csv").write_text(f"input,camera\ntake.npz,{too_long}\n")
    with pytest.raises(InputError, match="row 1: File name too long"):
        read_manifest(tmp_path / "m.csv")
    camera = tmp_path / "opencv.json"
    camera.write_text('{"camera_matrix": [1000, 0, 500, 0, 1000, 500, 0, 0, 1], "rvec": [0, 0, 0], '
                      '"tvec": [0, 0, 4], "image_width": 1' + "0" * 400 + ', "image_height": 1000}')
    with pytest.raises(InputError, match="image_width"):
        read_camera(camera)


def test_the_python_api_answers_bad_arguments_like_the_command_line(tmp_path):
    """Every bad argument an ``InputError`` naming it and the problem: never a bare ValueError, an IndexError, an
    OverflowError or an allocation of terabytes."""
    from ray3d import Camera, cameras
    from ray3d.demo import demo_clip
    from ray3d.io.world import World, read_world, write_world
    from ray3d.lifting.lifter import Lifter

    camera = cameras.h36m("S9", "54138969")
    document = camera.to_dict()
    pixels = camera.project(demo_clip()[:30])
    lifter = Lifter.load()
    cases = [
        (lambda: Camera.from_dict({**document, "fx": "abc"}), "camera field fx: not numeric"),
        (lambda: Camera.from_dict({**document, "cx": 10 ** 400}), "camera field cx: a number too large"),
        (lambda: Camera.from_dict([1, 2, 3]), "camera: expected a JSON object"),
        (lambda: lifter.lift([["a", "b"]] * 17, camera), "keypoints: not numeric"),
        (lambda: lifter.lift([[[1, 2]] * 17, [[1, 2]] * 16], camera), "keypoints: rows of different lengths"),
        (lambda: lifter.lift(pixels, camera, chunk=0), "chunk: frames per network call"),
        (lambda: lifter.lift_tracks({0: (["a", "b", "c"], pixels[:3])}, camera, "h36m17", 50),
         r"tracks\[0\]: frame ids: not numeric"),
        (lambda: lifter.lift_tracks({0: (np.zeros(0, int), pixels[:0])}, camera, "h36m17", 50),
         r"tracks\[0\]: no frames"),
        (lambda: lifter.lift_tracks({0: (np.array([0, 10 ** 12]), pixels[:2])}, camera, "h36m17", 50),
         r"tracks\[0\]: frame ids from 0 to 1000000000000 span"),
        (lambda: lifter.lift_tracks({0: (np.arange(30), pixels)}, Camera.from_dict({**document, "fy": 10 ** 400}),
                                    "h36m17", 50), "camera field fy: a number too large"),
    ]
    for call, message in cases:
        with pytest.raises(InputError, match=message):
            call()
    # A world file of the schema's older form (each track only its frames and joints) is read, the fields added
    # since absent; one without a field every version wrote is refused naming it.
    world = World({"0": lifter.lift(pixels, camera, fps=50.0)}, camera, lifter.name)
    write_world(tmp_path / "w.json", world)
    full = json.loads((tmp_path / "w.json").read_text())
    for entry in full["tracks"].values():
        for field in list(entry):
            if field not in ("frames", "joints"):
                del entry[field]
    (tmp_path / "old.json").write_text(json.dumps(full))
    old = read_world(tmp_path / "old.json")
    np.testing.assert_allclose(old.tracks["0"].joints, world.tracks["0"].joints, atol=1e-5)  # 5 decimals kept
    assert not old.tracks["0"].interpolated.any() and old.tracks["0"].refinement is None
    del full["tracks"]["0"]["frames"]
    (tmp_path / "broken.json").write_text(json.dumps(full))
    with pytest.raises(InputError, match=r"broken.json: tracks\['0'\]: not a world file written by ray3d: "
                                         r"missing field\(s\) frames"):
        read_world(tmp_path / "broken.json")


def test_a_job_and_its_whole_run_answer_bad_arguments_naming_them(tmp_path):
    """``Job``, ``run_job``, ``site_report`` and ``fuse_worlds``: a wrong type or value is an ``InputError`` naming
    the argument, before any work."""
    from ray3d import cameras
    from ray3d.demo import demo_clip
    from ray3d.fusion import fuse_worlds
    from ray3d.jobs import CameraChoice, Job, run_job, site_report

    camera = cameras.h36m("S9", "54138969")
    np.savez(tmp_path / "k.npz", keypoints=camera.project(demo_clip()[:30]), fps=50.0)
    one = (tmp_path / "k.npz",), (CameraChoice(made=camera),)
    cases = [(lambda: Job(*one, site=123), "site"), (lambda: Job(*one, every_s="x"), "every_s"),
             (lambda: Job(*one, every_s=-1.0), "every_s"), (lambda: Job(*one, start_time=5), "start_time"),
             (lambda: Job(*one).lifter("nonsense"), "nonsense"), (lambda: run_job(Job(*one), None), "out"),
             (lambda: site_report(None, None, tmp_path / "site"), "world"),
             (lambda: fuse_worlds([None, None]), "worlds")]
    for call, named in cases:
        with pytest.raises(InputError, match=named):
            call()
    assert not (tmp_path / "site").exists()


def test_evaluate_answers_bad_arguments_with_input_errors_naming_them(tmp_path, capsys):
    """``ray3d.evaluate.evaluate``: every bad argument an ``InputError`` naming it, before any work, never a bare
    ``ValueError``; the command line names its flags (issue 69)."""
    from ray3d import Camera
    from ray3d.data.motion import MotionSet
    from ray3d.data.virtual_cameras import grid
    from ray3d.evaluate import evaluate

    motion = MotionSet.from_clips([demo_clip()[:20].astype(np.float32)], clip_id=["walk"])
    seeing = grid("h36m")[:2]
    overhead = Camera.from_height_pitch(3.0, 20.0, (1000, 1000), hfov_deg=60.0)  # over the clip, not facing it
    cases = [
        (dict(refine=True), r"refine: needs a model that predicts every joint.*\(arguments: refine, model\)"),
        (dict(joints="coco17"), r"joints: expected one of h36m17, h36m14, got 'coco17' \(argument: joints\)"),
        (dict(cameras=[]), r"cameras: expected a non-empty list of Camera objects.*\(argument: cameras\)"),
        (dict(cameras="h36m"), r"cameras: expected a non-empty list of Camera objects.*, got str"),
        (dict(given_cameras=seeing[:1]), r"given_cameras: expected one for each of the 2 cameras, got 1"),
        (dict(bone_scale=0.0), r"bone_scale: expected a finite number above 0, got 0.0 \(argument: bone_scale\)"),
        (dict(noise_px=-1.0), r"noise_px: expected a finite number 0 or more, got -1.0"),
        (dict(noise_px=float("nan")), r"noise_px: expected a finite number 0 or more, got nan"),
        (dict(cameras=[overhead]), r"cameras: none of the 1 camera\(s\) sees any of the 1 clip\(s\) entirely"),
    ]
    for changes, message in cases:
        with pytest.raises(InputError, match=message):
            evaluate(**{"model": "rfrh", "motion": motion, "cameras": seeing, **changes})
    motion.save(tmp_path / "mine.npz")
    _fails_cleanly(capsys, ["evaluate", "--checkpoint", "rfrh", "--refine", "--mocap", str(tmp_path / "mine.npz"),
                            "--cameras", "h36m"], "refine: needs a model", "(--refine, --checkpoint)")


def _world_without_model(tmp_path, suffix):
    """A world file as another tool might write it: valid, but no ``model`` (the schema's optional field)."""
    from ray3d.io.world import LiftResult, World, write_world

    joints = demo_clip()[:6]
    path = write_world(tmp_path / f"w{suffix}", World({"7": LiftResult(joints, np.zeros((6, 17), bool), 30.0,
                                                                       np.arange(6))}, cameras.h36m("S9", "54138969"),
                                                        "test"))
    if suffix == ".json":
        document = json.loads(path.read_text())
        del document["model"]
        path.write_text(json.dumps(document))
    elif suffix == ".csv":
        path.write_text(path.read_text().replace("; model: test", "", 1))
    else:
        entries = dict(np.load(path))
        del entries["model"]
        np.savez(path, **entries)
    return path


@pytest.mark.parametrize("suffix", [".json", ".csv", ".npz"])
def test_a_world_file_without_the_optional_model_is_read_and_drawn(suffix, tmp_path, capsys):
    """``model`` is optional in world.schema.json: a file without it reads as model "unknown" and ``ray3d viz``
    draws it (issue 69)."""
    from importlib import resources

    import jsonschema

    path = _world_without_model(tmp_path, suffix)
    assert "model" not in path.read_text() if suffix != ".npz" else "model" not in np.load(path).files
    world = read_world(path)
    assert world.model == "unknown" and list(world.tracks) == ["7"]
    if suffix == ".json":
        schema = json.loads(resources.files("ray3d").joinpath("assets", "world.schema.json").read_text())
        jsonschema.validate(json.loads(path.read_text()), schema)
    assert main(["viz", str(path), "--html", str(tmp_path / "v.html")]) == 0
    assert (tmp_path / "v.html").exists() and "error" not in capsys.readouterr().err


def test_a_camera_looking_up_or_low_under_small_people_is_doubted(tmp_path, capsys):
    """A camera 0.3 m high looking 12 degrees up (a pitch of the wrong sign) is doubted by ``Camera.doubts`` and
    warned of in one line after the lift; one 0.28 m high whose people come out small is asked for its height
    (issue 69). Real cameras, and cameras looking level or down, raise neither."""
    from ray3d import Camera
    from ray3d.cli.printing import low_camera_doubts
    from ray3d.io.world import LiftResult

    looking_up = Camera.from_height_pitch(0.3, -12.0, (1000, 1002), hfov_deg=60.0, name="floor")
    assert looking_up.doubts() == ((), ("camera floor looks 12 degrees up from 0.30 m: is its pitch's sign right "
                                        "(positive looks down)? People are filmed from above or level",))
    for fine in (Camera.from_height_pitch(0.3, -3.0, (1000, 1002), hfov_deg=60.0),
                 Camera.from_height_pitch(2.5, 12.0, (1000, 1002), hfov_deg=60.0), cameras.h36m("S9", "54138969")):
        assert fine.doubts() == ((), ())

    def people(*statures):
        return {str(k): LiftResult(np.zeros((2, 17, 3)), np.zeros((2, 17), bool), 30.0, np.arange(2),
                                   refinement={"stature_m": s}) for k, s in enumerate(statures)}

    low = Camera.from_height_pitch(0.3, 0.0, (1000, 1002), hfov_deg=60.0, name="low")
    (doubt,) = low_camera_doubts(people(0.9, 1.0, 1.7), low)
    assert doubt.startswith("camera low stands 0.30 m over the floor, below a standing adult's hips, and its people "
                            "come out 1.00 m tall (median of 3): is its height in metres")
    assert low_camera_doubts(people(1.7, 1.65), low) == ()  # adults: the camera is believed
    assert low_camera_doubts(people(0.9), Camera.from_height_pitch(2.5, 12.0, (1000, 1002), hfov_deg=60.0)) == ()
    assert low_camera_doubts({}, low) == ()

    keypoints = tmp_path / "k.npz"
    np.savez(keypoints, keypoints=cameras.h36m("S9", "54138969").project(demo_clip()[:60]), fps=50.0)
    for pitch, needle in (("-12", "looks 12 degrees up from 0.28 m: is its pitch's sign right (positive looks "
                                  "down)?"),
                          ("-4", "stands 0.28 m over the floor, below a standing adult's hips")):
        out = tmp_path / f"o{pitch}.json"
        assert main(["lift", "--keypoints", str(keypoints), "--camera-height", "0.28", "--pitch", pitch, "--hfov",
                     "60", "--image-size", "1000x1002", "--out", str(out)]) == 0
        warnings = [line for line in capsys.readouterr().err.splitlines() if line.startswith("warning:")]
        assert len(warnings) == 1 and needle in warnings[0], warnings


def test_a_live_run_warns_of_a_camera_looking_up_once_its_streams_are_open():
    """``ray3d live`` says what ``Camera.doubts`` finds of each camera as it begins (once its streams are open, so
    a refusal before stays one line); a camera looking down says nothing."""
    from types import SimpleNamespace

    from ray3d import Camera
    from ray3d.jobs.live import LiveInputs, _said_at_the_start

    looking_up = Camera.from_height_pitch(0.3, -12.0, (1000, 1002), hfov_deg=60.0, name="floor")
    fine = Camera.from_height_pitch(2.5, 12.0, (1000, 1002), hfov_deg=60.0, name="door")
    said = _said_at_the_start(LiveInputs(SimpleNamespace(cameras=[fine, looking_up])), None, 2)
    assert said == ["warning: camera floor looks 12 degrees up from 0.30 m: is its pitch's sign right (positive "
                    "looks down)? People are filmed from above or level"]
    assert _said_at_the_start(LiveInputs(SimpleNamespace(cameras=[fine])), None, 1) == []


def test_frames_named_by_text_are_said_by_the_commands_that_read_them(tmp_path, capsys):
    """COCO-style results whose image_ids are text: ``ray3d lift`` and ``ray3d calibrate --from-person`` say how
    they numbered them and which frames came out, one note; integer ids say nothing (issue 69)."""
    pixels = cameras.h36m("S9", "54138969").project(demo_clip()[:40])
    flat = [np.concatenate([p, np.ones((17, 1))], 1).ravel().tolist() for p in pixels]

    def results(name, ids):
        path = tmp_path / name
        path.write_text(json.dumps([{"image_id": i, "keypoints": k, "score": 1.0} for i, k in zip(ids, flat)]))
        return path

    for name, ids, needle in (
            ("named.json", [f"frame_{k + 3:04d}.jpg" for k in range(40)],
             "named.json names its frames by text: ordered by the last number in each image name ('frame_000012.png'"
             " is frame 12), frames 3-42 (40 of them); if that is not the video's order, give each entry its frame "
             "number"),
            ("wordy.json", [f"view_{chr(97 + k // 26)}{chr(97 + k % 26)}.jpg" for k in range(40)],
             "wordy.json names its frames by text: ordered in the order the image names first appear in the file "
             "(they hold no number), frames 0-39 (40 of them)"),
            ("numbers.json", list(range(40)), None)):
        assert main(["lift", "--keypoints", str(results(name, ids)), "--layout", "h36m17", "--fps", "50",
                     "--camera", CAMERA, "--out", str(tmp_path / f"{name}.out.json")]) == 0
        notes = [line for line in capsys.readouterr().err.splitlines() if "by text" in line]
        assert len(notes) == (needle is not None) and all(n.startswith(f"note: {tmp_path / needle}") for n in notes)
    assert main(["calibrate", "--from-person", str(tmp_path / "named.json"), "--layout", "h36m17", "--image-size",
                 "1000x1002", "--out", str(tmp_path / "camera.json")]) == 0
    notes = [line for line in capsys.readouterr().err.splitlines() if "by text" in line]
    assert len(notes) == 1 and notes[0].startswith(f"note: {tmp_path / 'named.json'} names its frames by text")
