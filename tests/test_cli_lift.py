"""``ray3d lift`` end to end through every input and output format, on generated files; and bad input."""

from __future__ import annotations

import csv
import json

import cv2
import numpy as np
import pytest

from ray3d import InputError, cameras
from ray3d.cli import main
from ray3d.io.world import read_world
from ray3d.skeleton import BODY25, COCO17, H36M17, convert

CAMERA = cameras.h36m("S9", "55011271")
FRAMES = 12


def _world(frames=FRAMES):
    rng = np.random.default_rng(0)
    pose = rng.normal(0, 0.15, (17, 3)) + np.array([0, 0, 0.9])
    return pose[None] + np.linspace(-0.5, 0.5, frames)[:, None, None] * np.array([1.0, 0, 0])


def _coco_pixels():
    h36m = CAMERA.project(_world())
    pixels = np.zeros((FRAMES, 17, 2))
    for i, name in enumerate(COCO17.joint_names):
        pixels[:, i] = h36m[:, H36M17.index(name)] if name in H36M17.joint_names else h36m[:, 9]
    return pixels


def _inputs(tmp_path):
    """Every supported keypoint format, all holding the same detections (COCO-17 pixels, one person)."""
    pixels = _coco_pixels()
    scores = np.full((FRAMES, 17), 0.9)
    files = {}
    files["ours.npz"] = tmp_path / "ours.npz"
    np.savez(files["ours.npz"], keypoints=pixels, confidences=scores, layout="coco17", fps=60.0)
    files["ours.json"] = tmp_path / "ours.json"
    files["ours.json"].write_text(json.dumps({"layout": "coco17", "fps": 60, "detections": [
        {"frame": i, "track": 0, "keypoints": np.concatenate([pixels[i], scores[i, :, None]], -1).tolist()}
        for i in range(FRAMES)]}))
    files["ours.csv"] = tmp_path / "ours.csv"
    with files["ours.csv"].open("w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["frame", "track", "joint", "x", "y", "score"])
        for i in range(FRAMES):
            for j, name in enumerate(COCO17.joint_names):
                writer.writerow([i, 0, name, pixels[i, j, 0], pixels[i, j, 1], 0.9])
    files["coco.json"] = tmp_path / "coco.json"
    files["coco.json"].write_text(json.dumps([
        {"image_id": i, "category_id": 1, "score": 0.95,
         "keypoints": np.concatenate([pixels[i], scores[i, :, None]], -1).ravel().tolist()} for i in range(FRAMES)]
        + [{"image_id": 0, "category_id": 1, "score": 0.1, "keypoints": [0.0] * 51}]))  # a weaker second person
    flat = [np.concatenate([pixels[i], scores[i, :, None]], -1) for i in range(FRAMES)]
    files["alphapose-coco.json"] = tmp_path / "alphapose-results.json"  # tracked by PoseFlow: idx
    files["alphapose-coco.json"].write_text(json.dumps([
        {"image_id": f"{i}.jpg", "category_id": 1, "score": 2.8, "box": [10, 10, 50, 120], "idx": [3.0],
         "keypoints": flat[i].ravel().tolist()} for i in range(FRAMES)]))
    files["alphapose-halpe136.json"] = tmp_path / "alphapose-halpe136.json"  # whole body, untracked
    halpe = np.zeros((FRAMES, 136, 3))
    halpe[:, :17] = flat
    halpe[:, 17:26, :2] = pixels[:, [0, 5, 11, 15, 16, 15, 16, 15, 16]]
    halpe[:, 17:, 2] = 0.5
    files["alphapose-halpe136.json"].write_text(json.dumps([
        {"image_id": f"frame_{i:05d}.png", "category_id": 1, "score": 2.5, "keypoints": halpe[i].ravel().tolist()}
        for i in range(FRAMES)]))
    files["mmpose-video.json"] = tmp_path / "mmpose-video.json"
    files["mmpose-video.json"].write_text(json.dumps([
        {"frame_id": i, "instances": [{"keypoints": pixels[i].tolist(), "keypoint_scores": scores[i].tolist(),
                                       "bbox": [[0, 0, 99, 99]], "bbox_score": 0.9}]} for i in range(FRAMES)]))
    openpose = tmp_path / "openpose"
    openpose.mkdir()
    body25 = np.zeros((FRAMES, 25, 3))
    for j, name in enumerate(BODY25.joint_names):
        if name in COCO17.joint_names:
            body25[:, j, :2] = pixels[:, COCO17.index(name)]
            body25[:, j, 2] = 0.8
    for i in range(FRAMES):
        (openpose / f"video_{i:012d}_keypoints.json").write_text(json.dumps(
            {"version": 1.3, "people": [{"person_id": [-1], "pose_keypoints_2d": body25[i].ravel().tolist()}]}))
    files["openpose"] = openpose
    files["videopose3d.npz"] = tmp_path / "data_2d_custom.npz"
    h36m_pixels = convert(pixels, "coco17")
    np.savez_compressed(files["videopose3d.npz"], positions_2d={"S9": {"Walking": [h36m_pixels] * 4}},
                        metadata={"layout_name": "h36m"})
    return files


def _cameras(tmp_path):
    rvec, _ = cv2.Rodrigues(CAMERA.R)
    files = {"h36m": "h36m:S9:55011271"}
    files["ours.json"] = tmp_path / "camera.json"
    files["ours.json"].write_text(json.dumps(CAMERA.to_dict()))
    files["opencv.json"] = tmp_path / "opencv.json"
    files["opencv.json"].write_text(json.dumps({
        "camera_matrix": {"rows": 3, "cols": 3, "data": CAMERA.K.ravel().tolist()}, "dist_coeffs": CAMERA.dist.tolist(),
        "rvec": rvec.ravel().tolist(), "tvec": CAMERA.t.tolist(), "image_width": 1000, "image_height": 1000}))
    for suffix in ("yaml", "xml"):  # as OpenCV's FileStorage writes them (ray3d reads them without it)
        files[f"opencv.{suffix}"] = tmp_path / f"opencv.{suffix}"
        storage = cv2.FileStorage(str(files[f"opencv.{suffix}"]), cv2.FILE_STORAGE_WRITE)
        for key, value in (("camera_matrix", CAMERA.K), ("dist_coeffs", CAMERA.dist[None]), ("R", CAMERA.R),
                           ("t", CAMERA.t[:, None])):
            storage.write(key, value)
        storage.write("image_width", 1000)
        storage.write("image_height", 1000)
        storage.release()
    return files


def test_every_input_format_lifts_to_the_same_world(tmp_path, tiny_checkpoint, capsys):
    reference = None
    for name, path in _inputs(tmp_path).items():
        out = tmp_path / f"{name.replace('.', '_')}.npz"
        extra = ["--layout", "h36m17", "--subject", "S9", "--action", "Walking", "--camera-index", "1",
                 "--fps", "60"] if name == "videopose3d.npz" else []
        # The readers are compared, through the network alone: the refinement expects other body measures of a
        # detector's keypoints than of the videopose3d file's H36M-17 ones (its ankles, its size chain).
        code = main(["lift", "--keypoints", str(path), "--camera", "h36m:S9:55011271", "--out", str(out),
                     "--checkpoint", str(tiny_checkpoint), "--no-refine", *extra])
        assert code == 0, capsys.readouterr().err
        joints = read_world(out).track().joints
        assert joints.shape == (FRAMES, 17, 3)
        if reference is None:
            reference = joints
        np.testing.assert_allclose(joints, reference, atol=1e-4, err_msg=name)


def test_every_camera_format_gives_the_same_camera(tmp_path, tiny_checkpoint):
    from ray3d.io.camera_files import read_camera

    for name, spec in _cameras(tmp_path).items():
        camera = read_camera(spec)
        np.testing.assert_allclose(camera.R, CAMERA.R, atol=1e-9, err_msg=name)
        np.testing.assert_allclose(camera.t, CAMERA.t, atol=1e-9, err_msg=name)
        np.testing.assert_allclose(camera.K, CAMERA.K, atol=1e-9, err_msg=name)
        np.testing.assert_allclose(camera.dist, CAMERA.dist, atol=1e-12, err_msg=name)


def test_every_output_format_states_units_axes_joints_fps_camera(tmp_path, tiny_checkpoint):
    keypoints = _inputs(tmp_path)["ours.npz"]
    outputs = {}
    for suffix in ("json", "csv", "npz"):
        out = tmp_path / f"world.{suffix}"
        assert main(["lift", "--keypoints", str(keypoints), "--camera", str(_cameras(tmp_path)["ours.json"]),
                     "--out", str(out), "--checkpoint", str(tiny_checkpoint)]) == 0
        outputs[suffix] = read_world(out)
    for suffix, world in outputs.items():  # every format states them, and read_world gives them back
        assert world.units == "metres" and "z up" in world.axes, suffix
        assert list(world.joint_names) == list(H36M17.joint_names) and world.fps == 60.0, suffix
        assert world.camera.K[0, 0] == pytest.approx(CAMERA.K[0, 0]), suffix
    header = (tmp_path / "world.csv").read_text().splitlines()[0]
    assert "units: metres" in header and "z up" in header
    for suffix in ("csv", "npz"):
        np.testing.assert_allclose(outputs[suffix].track().joints, outputs["json"].track().joints, atol=2e-5)
        np.testing.assert_array_equal(outputs[suffix].track().interpolated, outputs["json"].track().interpolated)


def test_refuses_to_overwrite_without_force(tmp_path, tiny_checkpoint, capsys):
    keypoints = _inputs(tmp_path)["ours.npz"]
    out = tmp_path / "world.json"
    out.write_text("precious")
    args = ["lift", "--keypoints", str(keypoints), "--camera", "h36m:S9:55011271", "--out", str(out),
            "--checkpoint", str(tiny_checkpoint)]
    assert main(args) == 2
    assert "already exists" in capsys.readouterr().err and out.read_text() == "precious"
    assert main(args + ["--force"]) == 0 and out.read_text() != "precious"


@pytest.mark.parametrize("name, content, message", [
    ("wrong.npz", lambda p: np.savez(p, keypoints=np.zeros((4, 13, 2))), "13 joints per detection matches no layout"),
    ("text.json", lambda p: p.write_text(json.dumps({"detections": [{"keypoints": [["a", "b"]] * 17}]})),
     "not numeric"),
    ("empty.csv", lambda p: p.write_text(""), "the file is empty"),
    ("bad.csv", lambda p: p.write_text("frame,joint,x,y\n0,nose,1,oops\n"), "not numeric"),
    ("broken.json", lambda p: p.write_text("{"), "not valid JSON"),
])
def test_malformed_keypoints_give_one_line_and_exit_2(tmp_path, tiny_checkpoint, capsys, name, content, message):
    path = tmp_path / name
    content(path)
    code = main(["lift", "--keypoints", str(path), "--camera", "h36m:S9:55011271", "--out", str(tmp_path / "o.json"),
                 "--checkpoint", str(tiny_checkpoint)])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and message in err and str(path) in err


def test_camera_without_intrinsics_is_refused(tmp_path, tiny_checkpoint, capsys):
    camera = tmp_path / "noK.json"
    camera.write_text(json.dumps({"rvec": [0, 0, 0], "tvec": [0, 0, 3]}))
    keypoints = _inputs(tmp_path)["ours.npz"]
    code = main(["lift", "--keypoints", str(keypoints), "--camera", str(camera), "--out", str(tmp_path / "o.json"),
                 "--checkpoint", str(tiny_checkpoint)])
    err = capsys.readouterr().err
    assert code == 2 and "camera without intrinsics" in err and err.count("\n") == 1


def test_camera_from_height_and_pitch_flags(tmp_path, tiny_checkpoint, capsys):
    keypoints = _inputs(tmp_path)["ours.npz"]
    out = tmp_path / "w.json"
    assert main(["lift", "--keypoints", str(keypoints), "--camera-height", "1.6", "--pitch", "12", "--hfov", "60",
                 "--image-size", "1000x1000", "--out", str(out), "--checkpoint", str(tiny_checkpoint)]) == 0
    assert read_world(out).camera.name == "height1.6m-pitch12deg"
    assert main(["lift", "--keypoints", str(keypoints), "--pitch", "12", "--out", str(tmp_path / "x.json"),
                 "--checkpoint", str(tiny_checkpoint)]) == 2
    assert "--camera-height" in capsys.readouterr().err


def test_a_17_joint_file_is_read_as_the_layout_its_geometry_shows(tmp_path, tiny_checkpoint, capsys):
    coco = tmp_path / "coco_order.npz"
    np.savez(coco, keypoints=_coco_pixels())  # no layout stated: COCO-17 order
    h36m = tmp_path / "h36m_order.npz"
    np.savez(h36m, keypoints=CAMERA.project(_world()))
    worlds = {}
    for name, path, extra in (("guessed", coco, []), ("stated", coco, ["--layout", "coco17"]), ("h36m", h36m, [])):
        out = tmp_path / f"{name}.json"
        assert main(["lift", "--keypoints", str(path), "--camera", "h36m:S9:55011271", "--out", str(out),
                     "--checkpoint", str(tiny_checkpoint), *extra]) == 0
        worlds[name] = read_world(out).track().joints
    assert "coco17" in capsys.readouterr().out.splitlines()[0]
    np.testing.assert_array_equal(worlds["guessed"], worlds["stated"])


@pytest.mark.parametrize("name, pixels, message", [
    ("line.npz", lambda: np.tile(400 + np.r_[:17][:, None] * [0.0, 10.0], (FRAMES, 1, 1)),  # joints on a line
     "fits neither COCO-17 nor H36M-17; name the layout (--layout)"),
    ("normalised.npz", lambda: CAMERA.project(_world()) / 1000.0, "look normalised"),
    ("elsewhere.npz", lambda: CAMERA.project(_world()) + 5000.0,
     "elsewhere.npz: keypoints: 100% lie outside camera h36m:S9:55011271's 1000x1000"),
])
def test_keypoints_that_do_not_fit_are_refused(tmp_path, tiny_checkpoint, capsys, name, pixels, message):
    path, out = tmp_path / name, tmp_path / "never.json"
    np.savez(path, keypoints=pixels(), **({} if name == "line.npz" else {"layout": "h36m17"}))
    code = main(["lift", "--keypoints", str(path), "--camera", "h36m:S9:55011271", "--out", str(out),
                 "--checkpoint", str(tiny_checkpoint), "--fps", "30"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and message in err and not out.exists()


def test_a_file_without_a_frame_rate_says_which_it_assumed(tmp_path, tiny_checkpoint, capsys):
    path = tmp_path / "no_fps.npz"
    np.savez(path, keypoints=CAMERA.project(_world()), layout="h36m17")
    assert main(["lift", "--keypoints", str(path), "--camera", "h36m:S9:55011271", "--out", str(tmp_path / "w.json"),
                 "--checkpoint", str(tiny_checkpoint)]) == 0
    assert "states no frame rate: assumed the models' 60 fps" in capsys.readouterr().err


def test_detector_results_lists_keep_layout_tracks_and_scores(tmp_path):
    from ray3d.io.keypoints import read_keypoints
    pixels = _coco_pixels()
    halpe = np.concatenate([pixels, pixels[:, [0, 5, 11, 15, 16, 15, 16, 15, 16]]], axis=1)
    scores = np.linspace(0.2, 0.9, 26)
    path = tmp_path / "halpe26.json"
    path.write_text(json.dumps([{"image_id": f"{i}.jpg", "score": 1.0, "idx": i % 2,
                                 "keypoints": np.concatenate([halpe[i], scores[:, None]], -1).ravel().tolist()}
                                for i in range(FRAMES)]))
    read = read_keypoints(path)
    assert read.layout == "halpe26" and read.pixels.shape == (FRAMES, 26, 2)
    assert sorted(set(read.tracks.tolist())) == [0, 1]
    np.testing.assert_allclose(read.confidences[0], scores)
    np.testing.assert_allclose(convert(read.pixels, "halpe26"), convert(pixels, "coco17"), atol=1e-9)
    # One image's mmpose instances: every person is a track of frame 0.
    image = tmp_path / "mmpose-image.json"
    image.write_text(json.dumps([{"keypoints": pixels[k].tolist(), "keypoint_scores": [0.8] * 17, "bbox_score": 0.9}
                                 for k in range(3)]))
    read = read_keypoints(image)
    assert read.layout == "coco17" and read.tracks.tolist() == [0, 1, 2] and read.frames.tolist() == [0, 0, 0]
    np.testing.assert_allclose(read.pixels, pixels[:3])


@pytest.mark.parametrize("document, problem", [
    ([{"image_id": 0, "keypoints": [1.0] * 50}], "50 numbers"),
    ([{"image_id": 0, "idx": 1, "keypoints": [1.0] * 51}, {"image_id": 1, "keypoints": [1.0] * 51}],
     "some entries have a track id"),
    ([{"frame_id": 0, "instances": {"keypoints": []}}], "'instances' must be a list"),
    ([{"frame_id": 0, "instances": []}], "holds no person"),
    ([{"image_id": None, "keypoints": [1.0] * 51}], "'image_id'"),
    ([{"image_id": 0, "keypoints": [[1.0, 2.0]] * 17, "keypoint_scores": [0.5] * 16}], "confidences"),
    ([{"box": [0, 0, 1, 1]}], "'keypoints' in every entry"),
])
def test_bad_results_lists_name_the_problem(tmp_path, document, problem):
    from ray3d.io.keypoints import read_keypoints
    path = tmp_path / "results.json"
    path.write_text(json.dumps(document))
    with pytest.raises(InputError, match=problem):
        read_keypoints(path)


def test_camera_frame_output_and_bvh_through_the_cli(tmp_path, tiny_checkpoint, capsys):
    from ray3d.data.bvh import read_bvh
    files = _inputs(tmp_path)
    common = ["lift", "--keypoints", str(files["ours.npz"]), "--camera", "h36m:S9:55011271",
              "--checkpoint", str(tiny_checkpoint)]
    assert main([*common, "--out", str(tmp_path / "w.json")]) == 0
    assert main([*common, "--out", str(tmp_path / "c.csv"), "--frame", "camera"]) == 0
    assert "camera frame" in capsys.readouterr().out
    world, seen = read_world(tmp_path / "w.json"), read_world(tmp_path / "c.csv")
    assert world.frame == "world" and seen.frame == "camera" and "z forward" in seen.axes
    np.testing.assert_allclose(seen.track().joints, CAMERA.world_to_camera(world.track().joints), atol=2e-5)
    assert (seen.track().joints[..., 2] > 1.0).all()  # in front of the lens
    np.testing.assert_allclose(seen.in_frame("world").track().joints, world.track().joints, atol=2e-5)
    assert main([*common, "--out", str(tmp_path / "c.trc"), "--frame", "camera"]) == 2
    assert "world frame" in capsys.readouterr().err and not (tmp_path / "c.trc").exists()
    assert main([*common, "--out", str(tmp_path / "w.bvh")]) == 0
    motion = read_bvh(tmp_path / "w.bvh")
    assert len(motion.motion) == FRAMES and motion.fps == pytest.approx(60.0)
    assert main(["viz", str(tmp_path / "c.csv"), "--html", str(tmp_path / "v.html")]) == 0


def test_people_left_out_of_an_untracked_results_list_are_reported(tmp_path, tiny_checkpoint, capsys):
    from ray3d.io.keypoints import read_keypoints
    files = _inputs(tmp_path)
    assert read_keypoints(files["coco.json"]).untracked_dropped == 1  # the weaker second person of frame 0
    assert read_keypoints(files["alphapose-coco.json"]).untracked_dropped == 0  # tracked: everybody kept
    assert main(["lift", "--keypoints", str(files["coco.json"]), "--camera", "h36m:S9:55011271",
                 "--out", str(tmp_path / "w.json"), "--checkpoint", str(tiny_checkpoint)]) == 0
    assert "1 other detection(s) left out" in capsys.readouterr().err


def test_our_bvh_export_reads_back_through_our_importer_within_a_centimetre(tmp_path, capsys):
    """``ray3d lift --out w.bvh`` then ``ray3d data import-bvh w.bvh``: the same joints, metres, floor kept."""
    from ray3d.data.motion import MotionSet
    from ray3d.demo import demo_clip

    np.savez(tmp_path / "kp.npz", keypoints=CAMERA.project(demo_clip()[:90]), layout="h36m17", fps=60.0)
    common = ["lift", "--keypoints", str(tmp_path / "kp.npz"), "--camera", "h36m:S9:55011271"]
    assert main([*common, "--out", str(tmp_path / "w.json")]) == 0
    assert main([*common, "--out", str(tmp_path / "w.bvh")]) == 0
    assert main(["data", "import-bvh", str(tmp_path / "w.bvh"), "--out", str(tmp_path / "m.npz")]) == 0
    assert "ray3d" not in capsys.readouterr().err
    lifted = read_world(tmp_path / "w.json").track().joints
    imported = MotionSet.load(tmp_path / "m.npz").clip(0)
    assert imported.shape == lifted.shape
    assert np.abs(imported - lifted).max() < 0.01


def test_the_model_follows_the_keypoints_layout_unless_one_is_named(tmp_path, capsys):
    """H36M-17 keypoints: ray3d; a detector's layout: ray3d-real, trained for detectors; --checkpoint wins."""
    from ray3d.checkpoints import default_model
    from ray3d.lifting.files import lift_file

    assert default_model("h36m17") == "ray3d" and {default_model(n) for n in ("coco17", "body25", "blazepose33",
                                                                              "halpe26")} == {"ray3d-real"}
    files = _inputs(tmp_path)
    files["h36m.npz"] = tmp_path / "h36m.npz"
    np.savez(files["h36m.npz"], keypoints=CAMERA.project(_world()), layout="h36m17", fps=60.0)
    for name, model in (("h36m.npz", "ray3d"), ("coco.json", "ray3d-real")):
        _, world = lift_file(files[name], CAMERA, tmp_path / f"{name}.json")
        assert world.model == model, name
    assert main(["lift", "--keypoints", str(files["coco.json"]), "--camera", "h36m:S9:55011271",
                 "--out", str(tmp_path / "cli.json")]) == 0
    assert "with ray3d-real through camera" in capsys.readouterr().out
    assert main(["lift", "--keypoints", str(files["coco.json"]), "--camera", "h36m:S9:55011271", "--checkpoint",
                 "ray3d", "--out", str(tmp_path / "named.json")]) == 0
    assert read_world(tmp_path / "named.json").model == "ray3d"


def test_an_implausible_camera_is_warned_of_and_an_unusable_lens_refused(tmp_path, tiny_checkpoint, capsys):
    """A camera 0.3 m up looking 30 degrees up still lifts, with one warning that the floor is out of view; a
    lens whose distortion turns back inside the image is refused in one line (issue 49)."""
    keypoints = _inputs(tmp_path)["ours.npz"]
    assert main(["lift", "--keypoints", str(keypoints), "--camera-height", "0.3", "--pitch", "-30", "--hfov", "50",
                 "--image-size", "1000x1000", "--out", str(tmp_path / "up.json"), "--checkpoint",
                 str(tiny_checkpoint)]) == 0
    warnings = [line for line in capsys.readouterr().err.splitlines() if line.startswith("warning:")]
    assert any("above the horizon" in line for line in warnings)
    camera = cameras.h36m("S9", "55011271").to_dict()
    camera["dist"] = [-0.9, 0, 0, 0, 0]
    path = tmp_path / "folding.json"
    path.write_text(json.dumps(camera))
    code = main(["lift", "--keypoints", str(keypoints), "--camera", str(path), "--out", str(tmp_path / "o.json"),
                 "--checkpoint", str(tiny_checkpoint)])
    err = capsys.readouterr().err
    assert code == 2 and "turns back" in err and err.count("\n") == 1 and not (tmp_path / "o.json").exists()
