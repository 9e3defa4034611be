"""The bad-input catalogue: every command and reader given something wrong. Each case must end in exit code 2
with one line on stderr that names the file or the field (the case's needle), no traceback, no file changed
and nothing written. (tests/test_bad_input.py holds the cases that need their own checks.)"""

from __future__ import annotations

import json

import numpy as np
import pytest

from ray3d import cameras
from ray3d.cli import main
from ray3d.demo import demo_clip
from ray3d.io.world import LiftResult, World, write_world

CAMERA = cameras.h36m("S9", "54138969")
H36M = "h36m:S9:54138969"


def _pixels(frames=12):
    return CAMERA.project(demo_clip()[:frames])


def _write(tmp, name, text):
    path = tmp / name
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(text)
    return path


def _npz(tmp, name="k.npz", **arrays):
    path = tmp / name
    np.savez(path, **({"keypoints": _pixels()} | arrays))
    return path


def _camera_json(tmp, name="camera.json", **changes):
    return _write(tmp, name, json.dumps(CAMERA.to_dict() | changes))


def _world(tmp, name="w.json"):
    joints = demo_clip()[:6]
    return write_world(tmp / name, World({"7": LiftResult(joints, np.zeros((6, 17), bool), 30.0, np.arange(6))},
                                         CAMERA, "test"))


def _lift(keypoints, *extra, camera=H36M, out="out.json"):
    return ["lift", "--keypoints", str(keypoints), "--camera", str(camera), "--out", str(keypoints.parent / out),
            *extra]


def _results(tmp, document, name="results.json"):
    return _lift(_write(tmp, name, json.dumps(document)))


def _openpose(tmp, people):
    folder = tmp / "openpose"
    folder.mkdir()
    (folder / "v_000000000000_keypoints.json").write_text(json.dumps({"people": people}))
    return _lift(folder)


def _opencv_json(tmp, **matrix):
    """The test camera in OpenCV's JSON form, its camera_matrix {rows, cols, dt, data} changed by ``matrix``."""
    document = {"camera_matrix": {"rows": 3, "cols": 3, "dt": "d", "data": np.asarray(CAMERA.K).ravel().tolist()}
                | matrix, "dist_coeffs": np.asarray(CAMERA.dist).tolist(), "R": np.asarray(CAMERA.R).tolist(),
                "t": np.asarray(CAMERA.t).tolist(), "image_width": CAMERA.image_size[0],
                "image_height": CAMERA.image_size[1]}
    return _write(tmp, "c.json", json.dumps(document))


def _opencv_xml(tmp, rows="3", data=None):
    """The test camera's matrix in OpenCV's XML storage, its rows and data as given (text, as the file holds it)."""
    data = " ".join(f"{v:.16e}" for v in np.asarray(CAMERA.K).ravel()) if data is None else data
    return _write(tmp, "c.xml", f'<?xml version="1.0"?>\n<opencv_storage><image_width>{CAMERA.image_size[0]}'
                                f'</image_width><camera_matrix type_id="opencv-matrix"><rows>{rows}</rows><cols>3'
                                f'</cols><dt>d</dt><data>{data}</data></camera_matrix></opencv_storage>\n')


def _floor(tmp, rows, name="floor.csv"):
    path = _write(tmp, name, "x,y,u,v\n" + "".join(",".join(map(str, r)) + "\n" for r in rows))
    return ["calibrate", "--floor-points", str(path), "--hfov", "60", "--image-size", "1000x1000",
            "--out", str(tmp / "cam.json")]


ROTATION = np.asarray(CAMERA.R)
CASES = {
    # --- keypoint files (ray3d lift) -------------------------------------------------------------------------
    "keypoints: missing file": (lambda t: _lift(t / "none.npz"), "none.npz"),
    "keypoints: unknown suffix": (lambda t: _lift(_write(t, "k.txt", "1 2 3")), "k.txt"),
    "keypoints: empty file": (lambda t: _lift(_write(t, "k.json", "")), "empty"),
    "keypoints: npz without keypoints": (lambda t: _lift(_npz(t, "p.npz", keypoints=np.zeros(3), other=1)), "p.npz"),
    "keypoints: npz of (N, 17, 3)": (lambda t: _lift(_npz(t, keypoints=np.zeros((4, 17, 3)))), "keypoints"),
    "keypoints: npz confidences of the wrong shape": (lambda t: _lift(_npz(t, confidences=np.ones((3, 17)))),
                                                      "confidences"),
    "keypoints: npz negative fps": (lambda t: _lift(_npz(t, fps=-5.0)), "fps"),
    "keypoints: npz strings": (lambda t: _lift(_npz(t, keypoints=np.array([["a"] * 2] * 17)[None])), "k.npz"),
    "keypoints: normalised to 0-1": (lambda t: _lift(_npz(t, keypoints=_pixels() / 1000.0)), "normalised"),
    "keypoints: outside the image": (lambda t: _lift(_npz(t, keypoints=_pixels() + 5000.0)), "image"),
    "keypoints: 33 joints named coco17": (lambda t: _lift(_npz(t, keypoints=np.zeros((3, 33, 2))), "--layout",
                                                          "coco17"), "33"),
    "keypoints: 20 joints": (lambda t: _lift(_npz(t, keypoints=np.zeros((3, 20, 2)))), "20 joints"),
    "keypoints: the root never seen": (lambda t: _lift(_npz(t, keypoints=np.where(
        np.arange(17)[None, :, None] == 0, np.nan, _pixels())), "--layout", "h36m17"), "the root (pelvis"),
    "keypoints: ours, detections empty": (lambda t: _lift(_write(t, "k.json", '{"detections": []}')), "detections"),
    "keypoints: ours, keypoints missing": (lambda t: _lift(_write(t, "k.json", '{"detections": [{"frame": 0}]}')),
                                           "keypoints"),
    "keypoints: ours, text values": (lambda t: _lift(_write(t, "k.json", json.dumps(
        {"detections": [{"keypoints": [["x", "y"]] * 17}]}))), "not numeric"),
    "keypoints: ours, an OpenPose file": (lambda t: _lift(_write(t, "k.json", '{"people": []}')), "folder"),
    "keypoints: CSV without x": (lambda t: _lift(_write(t, "k.csv", "frame,joint,y\n0,pelvis,1\n")), "header"),
    "keypoints: CSV text x": (lambda t: _lift(_write(t, "k.csv", "frame,joint,x,y\n0,pelvis,a,1\n")),
                              "not numeric"),
    "keypoints: CSV joints differ by frame": (lambda t: _lift(_write(
        t, "k.csv", "frame,joint,x,y\n0,a,1,1\n0,b,1,1\n1,a,1,1\n")), "same joints"),
    "keypoints: COCO list of 50 numbers": (lambda t: _results(t, [{"image_id": 0, "keypoints": [1.0] * 50}]),
                                           "50 numbers"),
    "keypoints: AlphaPose idx on some entries only": (lambda t: _results(t, [
        {"image_id": "0.jpg", "idx": 1, "keypoints": [1.0] * 51}, {"image_id": "1.jpg", "keypoints": [1.0] * 51}]),
        "track id"),
    "keypoints: mmpose instances not a list": (lambda t: _results(t, [{"frame_id": 0, "instances": {}}]),
                                               "instances"),
    "keypoints: mmpose video with nobody": (lambda t: _results(t, [{"frame_id": 0, "instances": []}]), "no person"),
    "keypoints: results list of boxes only": (lambda t: _results(t, [{"bbox": [1, 2, 3, 4]}]), "keypoints"),
    "keypoints: COCO image_id 1.5": (lambda t: _results(t, [{"image_id": 1.5, "keypoints": [1.0] * 51}]),
                                     "image_id 1.5: not a frame number"),
    "keypoints: COCO image_id a list": (lambda t: _results(t, [{"image_id": [3], "keypoints": [1.0] * 51}]),
                                        "image_id: expected a frame number or an image name, got [3]"),
    "keypoints: COCO image_ids of two videos": (lambda t: _results(t, [
        {"image_id": f"{video}/{frame:04d}.jpg", "keypoints": [1.0] * 51} for video in ("a", "b") for frame in (1, 2)]),
        "image_id: 'a/0001.jpg' and 'b/0001.jpg' both read as frame 1"),
    "keypoints: COCO image_ids of names and numbers": (lambda t: _results(t, [
        {"image_id": 0, "keypoints": [1.0] * 51}, {"image_id": "left.jpg", "keypoints": [1.0] * 51}]),
        "image_id: 1 image name(s) hold no number ('left.jpg') beside frames given by number"),
    "keypoints: mmpose frame_id 2.5": (lambda t: _results(t, [{"frame_id": 2.5, "instances": [
        {"keypoints": [[1.0, 1.0]] * 17}]}]), "frame_id 2.5: not a frame number"),
    "keypoints: OpenPose folder empty": (lambda t: _lift((t / "empty").mkdir() or t / "empty"), "OpenPose"),
    "keypoints: OpenPose 20 numbers": (lambda t: _openpose(t, [{"pose_keypoints_2d": [1.0] * 20}]), "75"),
    "keypoints: OpenPose nobody": (lambda t: _openpose(t, []), "no person"),
    "keypoints: VideoPose3D npz without a subject": (lambda t: _lift(_npz(
        t, "d.npz", positions_2d={"S1": {"Walk": [np.zeros((4, 17, 2))]}}, allow=1), "--subject", "S9"), "S9"),
    # --- camera files and flags -------------------------------------------------------------------------------
    "camera: missing file": (lambda t: _lift(_npz(t), camera=t / "nope.json"), "nope.json"),
    "camera: no fx": (lambda t: _lift(_npz(t), camera=_write(t, "c.json", json.dumps(
        {k: v for k, v in CAMERA.to_dict().items() if k != "fx"}))), "fx"),
    "camera: R not a rotation": (lambda t: _lift(_npz(t), camera=_camera_json(t, R=(2 * ROTATION).tolist())), "R"),
    "camera: dist of 2": (lambda t: _lift(_npz(t), camera=_camera_json(t, dist=[0.1, 0.2])), "dist"),
    "camera: negative width": (lambda t: _lift(_npz(t), camera=_camera_json(t, width=-1000)), "width"),
    "camera: NaN focal": (lambda t: _lift(_npz(t), camera=_write(t, "c.json", json.dumps(
        CAMERA.to_dict()).replace('"fx": 1145.04940458804', '"fx": NaN'))), "camera field fx: contains NaN"),
    "camera: YAML without camera_matrix": (lambda t: _lift(_npz(t), camera=_write(
        t, "c.yaml", "%YAML:1.0\nimage_width: 10\n")), "camera_matrix"),
    "camera: unknown bundled camera": (lambda t: _lift(_npz(t), camera="h36m:S99:1"), "S99"),
    "camera: OpenCV JSON rows null": (lambda t: _lift(_npz(t), camera=_opencv_json(t, rows=None)),
                                      "c.json: camera_matrix.rows: expected a whole number 1-16, got null"),
    "camera: OpenCV JSON cols null": (lambda t: _lift(_npz(t), camera=_opencv_json(t, cols=None)),
                                      "c.json: camera_matrix.cols: expected a whole number 1-16, got null"),
    "camera: OpenCV JSON data not a list": (lambda t: _lift(_npz(t), camera=_opencv_json(t, data=5)),
                                            "c.json: camera_matrix.data: expected a list of numbers, got 5"),
    "camera: OpenCV JSON data null": (lambda t: _lift(_npz(t), camera=_opencv_json(t, data=None)),
                                                "c.json: camera_matrix.data: expected a list of numbers, got null"),
    "camera: OpenCV XML rows empty": (lambda t: _lift(_npz(t), camera=_opencv_xml(t, rows="")),
                                      "c.xml: camera_matrix.rows: expected a whole number 1-16, got null"),
    "camera: OpenCV XML rows text": (lambda t: _lift(_npz(t), camera=_opencv_xml(t, rows="three")),
                                     "c.xml: camera_matrix.rows: expected a whole number 1-16, got 'three'"),
    "camera: OpenCV XML data text": (lambda t: _lift(_npz(t), camera=_opencv_xml(t, data="1 0 x 0 1 0 0 0 1")),
                                     "c.xml: camera_matrix.data: not numeric"),
    "camera: a misspelt dist": (lambda t: _lift(_npz(t), camera=_write(t, "c.json", json.dumps(
        {("dsit" if k == "dist" else k): v for k, v in CAMERA.to_dict().items()}))),
                               "unknown key 'dsit' (did you mean 'dist'?)"),
    "camera: a misspelt floor_z_m": (lambda t: _lift(_npz(t), camera=_camera_json(t, floor_zm=-0.5)),
                                     "unknown key 'floor_zm' (did you mean 'floor_z_m'?)"),
    "site: a zone crossing itself": (lambda t: ["site", str(_world(t)), "--site", str(_write(t, "s.json", json.dumps(
        {"zones": [{"name": "till", "polygon": [[0, 0], [2, 1], [2, 0], [0, 1]]}]}))), "--out", str(t / "o")],
                                     "zone 'till' crosses itself"),
    "camera: --image-size without x": (lambda t: ["lift", "--keypoints", str(_npz(t)), "--camera-height", "3",
                                                  "--pitch", "20", "--hfov", "60", "--image-size", "1000",
                                                  "--out", str(t / "o.json")], "image-size"),
    "camera: --hfov 200": (lambda t: ["lift", "--keypoints", str(_npz(t)), "--camera-height", "3", "--pitch", "20",
                                      "--hfov", "200", "--image-size", "1000x1000", "--out", str(t / "o.json")],
                           "hfov"),
    "camera: looking at the sky": (lambda t: ["lift", "--keypoints", str(_npz(t)), "--camera-height", "3",
                                              "--pitch", "-60", "--hfov", "60", "--image-size", "1000x1002",
                                              "--out", str(t / "o.json")], "above the horizon"),
    "camera: no camera at all": (lambda t: ["lift", "--keypoints", str(_npz(t)), "--out", str(t / "o.json")],
                                 "camera"),
    # --- outputs ----------------------------------------------------------------------------------------------
    "out: unknown suffix": (lambda t: _lift(_npz(t), out="o.xyz"), "o.xyz"),
    "out: exists": (lambda t: _lift(_npz(t), out=_write(t, "o.json", "{}").name), "already exists"),
    "out: TRC in the camera frame": (lambda t: _lift(_npz(t), "--frame", "camera", out="o.trc"), "world frame"),
    "out: BVH in the camera frame": (lambda t: _lift(_npz(t), "--frame", "camera", out="o.bvh"), "world frame"),
    "out: bad --smooth-3d": (lambda t: _lift(_npz(t), "--smooth-3d", "kalman"), "--smooth-3d"),
    "out: bad --frame": (lambda t: _lift(_npz(t), "--frame", "body"), "--frame"),
    # --- viz --------------------------------------------------------------------------------------------------
    "viz: missing world file": (lambda t: ["viz", str(t / "w.json"), "--html", str(t / "v.html")], "w.json"),
    "viz: not a world file": (lambda t: ["viz", str(_write(t, "w.json", '{"tracks": 3}')), "--html",
                                         str(t / "v.html")], "w.json"),
    "viz: unknown track": (lambda t: ["viz", str(_world(t)), "--track", "9", "--html", str(t / "v.html")], "9"),
    "viz: nothing to write": (lambda t: ["viz", str(_world(t))], "--html"),
    "viz: fps 0": (lambda t: ["viz", str(_world(t)), "--fps", "0", "--html", str(t / "v.html")], "fps"),
    "viz: animation .avi": (lambda t: ["viz", str(_world(t)), "--animation", str(t / "a.avi")], "a.avi"),
    "viz: world suffix .txt": (lambda t: ["viz", str(_write(t, "w.txt", "x")), "--html", str(t / "v.html")],
                               "w.txt"),
    # --- calibrate --------------------------------------------------------------------------------------------
    "calibrate: 3 floor points": (lambda t: _floor(t, [(0, 0, 1, 1), (1, 0, 2, 1), (0, 1, 1, 2)]), "at least"),
    "calibrate: collinear floor points": (lambda t: _floor(t, [(k, 0, 100 + 50 * k, 500) for k in range(5)]),
                                          "one line"),
    "calibrate: floor points without v": (lambda t: ["calibrate", "--floor-points", str(_write(
        t, "floor.csv", "x,y,u\n0,0,1\n")), "--hfov", "60", "--image-size", "1000x1000", "--out",
        str(t / "c.json")], "floor.csv"),
    "calibrate: nothing to calibrate from": (lambda t: ["calibrate", "--out", str(t / "c.json")], "floor-points"),
    "calibrate: person file missing": (lambda t: ["calibrate", "--from-person", str(t / "p.npz"), "--image-size",
                                                  "1000x1000", "--out", str(t / "c.json")], "p.npz"),
    # --- models, training, evaluation, batch, data -------------------------------------------------------------
    "lift: checkpoint missing": (lambda t: _lift(_npz(t), "--checkpoint", str(t / "m.safetensors")),
                                 "m.safetensors"),
    "lift: checkpoint not safetensors": (lambda t: _lift(_npz(t), "--checkpoint", str(_write(
        t, "m.safetensors", b"\x00" * 64))), "m.safetensors"),
    "train: config missing": (lambda t: ["train", "--config", str(t / "c.json"), "--out", str(t / "run")],
                              "c.json"),
    "train: config not JSON": (lambda t: ["train", "--config", str(_write(t, "c.json", "{")), "--out",
                                          str(t / "run")], "c.json"),
    "train: config with an unknown field": (lambda t: ["train", "--config", str(_write(
        t, "c.json", '{"preset": "ray3d", "learning_rat": 1}')), "--out", str(t / "run")], "learning_rat"),
    "train: unknown preset": (lambda t: ["train", "--preset", "ray4d", "--out", str(t / "run")], "ray4d"),
    "evaluate: unknown camera set": (lambda t: ["evaluate", "--cameras", "moon"], "moon"),
    "export: checkpoint missing": (lambda t: ["export", "--checkpoint", str(t / "run.safetensors"), "--out",
                                              str(t / "m.safetensors")], "run.safetensors"),
    "batch: manifest missing": (lambda t: ["batch", str(t / "jobs.csv"), "--out", str(t / "out")], "jobs.csv"),
    "batch: manifest with an unknown column": (lambda t: ["batch", str(_write(
        t, "jobs.csv", "input,camera,colour\na.npz,c.json,red\n")), "--out", str(t / "out")], "colour"),
    "data: import a BVH that is not one": (lambda t: ["data", "import-bvh", str(_write(t, "a.bvh", "MOTION\n")),
                                                      "--out", str(t / "m.npz")], "a.bvh"),
    "command: unknown": (lambda t: ["fly"], "fly"),
}


def _snapshot(folder):
    return {p: p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.mark.parametrize("case", sorted(CASES))
def test_bad_input_ends_in_one_line_and_changes_nothing(case, tmp_path, capsys):
    build, needle = CASES[case]
    argv = build(tmp_path)
    before = _snapshot(tmp_path)
    capsys.readouterr()
    try:
        code = main(argv)
    except SystemExit as exit_:  # argparse's own exit
        code = exit_.code
    err = capsys.readouterr().err.strip()
    assert code == 2, (case, err)
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert needle in err, err
    assert _snapshot(tmp_path) == before, "a file was changed or written"
