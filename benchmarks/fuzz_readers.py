"""Fuzz every file reader: valid files of each format (keypoints JSON / CSV / npz, AlphaPose and mmpose results,
camera JSON / YAML / OpenCV JSON / calibration TOML, world JSON / CSV / npz, floor points CSV, BVH, site JSON / YAML,
floor regions, batch manifests CSV / JSON, OpenPose frames, checkpoint JSON) mutated at random (bytes flipped, cut,
repeated, inserted) and read back.
A reader may return a result or raise ``InputError``; anything else is a crash and is listed.

    python benchmarks/fuzz_readers.py --files 10000 [--seed 0] [--out DIR]
"""

from __future__ import annotations

import argparse
import collections
import json
import tempfile
import time
from pathlib import Path

import cv2
import numpy as np

from ray3d import InputError, cameras
from ray3d.batch import read_manifest
from ray3d.checkpoints import load_model, resolve
from ray3d.data.bvh import read_bvh
from ray3d.demo import demo_clip
from ray3d.io.camera_files import read_camera, read_floor, save_cameras
from ray3d.io.floor_points import read_floor_points
from ray3d.io.keypoints import Keypoints, read_keypoints, write_keypoints_json
from ray3d.io.world import LiftResult, World, read_world, write_world
from ray3d.site.files import read_site


def seeds(folder: Path) -> dict[Path, object]:
    """{valid file: its reader}, one file per format."""
    camera = cameras.h36m("S9", "54138969")
    clip = demo_clip()[:8]
    pixels = camera.project(clip)
    files = {}
    np.savez(folder / "k.npz", keypoints=pixels, fps=50.0)
    keypoints = Keypoints(pixels, np.ones(pixels.shape[:2]), np.arange(8), np.zeros(8, dtype=int), "h36m17", 50.0,
                          "seed")
    write_keypoints_json(folder / "k.json", keypoints)
    with open(folder / "k.csv", "w") as f:
        f.write("frame,joint,x,y,score\n" + "".join(f"{t},{j},{pixels[t, j, 0]:.2f},{pixels[t, j, 1]:.2f},1\n"
                                                     for t in range(8) for j in range(17)))
    files.update({folder / "k.npz": read_keypoints, folder / "k.json": read_keypoints,
                  folder / "k.csv": read_keypoints})
    save_cameras(folder / "c.json", [camera])
    K = camera.K
    (folder / "c.yaml").write_text(
        "%YAML:1.0\ncamera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 3\n   dt: d\n   data: ["
        + ", ".join(f"{v:.3f}" for v in K.ravel()) + "]\nrvec: !!opencv-matrix\n   rows: 3\n   cols: 1\n   dt: d\n"
        "   data: [0.1, 0.2, 0.3]\ntvec: !!opencv-matrix\n   rows: 3\n   cols: 1\n   dt: d\n   data: [0, 0, 4]\n"
        "image_width: 1000\nimage_height: 1002\n")
    rvec, tvec = cv2.Rodrigues(camera.R)[0].ravel().tolist(), camera.t.tolist()
    (folder / "opencv.json").write_text(json.dumps({
        "camera_matrix": {"rows": 3, "cols": 3, "data": K.ravel().round(3).tolist()}, "dist_coeffs": [0.01, 0, 0, 0, 0],
        "rvec": rvec, "tvec": tvec, "image_width": 1000, "image_height": 1002}))
    (folder / "calibration.toml").write_text(
        f"[cam_01]\nname = \"cam_01\"\nsize = [1000.0, 1002.0]\nmatrix = {np.round(K, 3).tolist()}\n"
        f"distortions = [0.01, 0.0, 0.0, 0.0]\nrotation = {rvec}\ntranslation = {tvec}\nfisheye = false\n")
    files.update({folder / "c.json": read_camera, folder / "c.yaml": read_camera, folder / "opencv.json": read_camera,
                  folder / "calibration.toml": read_camera})
    world = World({"0": LiftResult(clip, np.zeros((8, 17), dtype=bool), 50.0, np.arange(8))}, camera, "seed")
    for suffix in (".json", ".csv", ".npz"):
        write_world(folder / f"w{suffix}", world)
        files[folder / f"w{suffix}"] = read_world
    (folder / "f.csv").write_text("x,y,u,v\n0,0,10,10\n1,0,20,10\n1,1,20,20\n0,1,10,20\n")
    files[folder / "f.csv"] = read_floor_points
    coco = np.concatenate([pixels, np.ones((8, 17, 1))], axis=-1)
    (folder / "alphapose.json").write_text(json.dumps([{"image_id": f"{t}.jpg", "score": 2.5, "idx": [1.0],
                                                        "keypoints": coco[t].ravel().tolist()} for t in range(8)]))
    (folder / "mmpose.json").write_text(json.dumps([{"frame_id": t, "instances": [
        {"keypoints": pixels[t].tolist(), "keypoint_scores": [0.9] * 17, "bbox_score": 0.8}]} for t in range(8)]))
    files.update({folder / "alphapose.json": read_keypoints, folder / "mmpose.json": read_keypoints})
    write_world(folder / "b.bvh", world)
    files[folder / "b.bvh"] = lambda path: read_bvh(path).positions()
    (folder / "site.json").write_text(json.dumps({
        "zones": [{"name": "room", "polygon": [[0, 0], [4, 0], [4, 3]], "max_occupancy": 2, "max_dwell_s": 30}],
        "lines": [{"name": "door", "start": [0, -1], "end": [0, 1]}]}))
    (folder / "site.yaml").write_text("zones:\n  - name: room\n    polygon: [[0, 0], [4, 0], [4, 3]]\n"
                                      "lines:\n  - {name: door, start: [0, -1], end: [0, 1]}\n")
    (folder / "floor.json").write_text(json.dumps({"floor_regions": [
        {"name": "stage", "polygon": [[0, 0], [2, 0], [2, 2]], "height_m": 0.3},
        {"name": "ramp", "polygon": [[3, 0], [5, 0], [5, 2]], "vertex_heights_m": [0, 0.2, 0.2]}]}))
    (folder / "m.csv").write_text("input,camera,fps,flip_test,every\nk.npz,h36m:S9:54138969,50,yes,15min\n")
    (folder / "m.json").write_text(json.dumps({"inputs": [{"input": "k.npz", "camera_height": 3, "pitch": 20,
                                                           "hfov": 60, "image_size": "1000x1000"}]}))
    files.update({folder / "site.json": read_site, folder / "site.yaml": read_site, folder / "floor.json": read_floor,
                  folder / "m.csv": read_manifest, folder / "m.json": read_manifest})
    (folder / "openpose.json").write_text(json.dumps({"version": 1.3, "people": [
        {"person_id": [-1], "pose_keypoints_2d": [float(v) for _ in range(25) for v in (400.0, 300.0, 0.8)]}]}))
    files[folder / "openpose.json"] = lambda path: read_keypoints(_in_folder(path, "openpose", "0_keypoints.json"))
    weights = resolve("ray3d")
    (folder / "checkpoint.json").write_bytes(weights.with_suffix(".json").read_bytes())
    (folder / "checkpoint").mkdir()
    (folder / "checkpoint" / "m.safetensors").write_bytes(weights.read_bytes())
    files[folder / "checkpoint.json"] = lambda path: load_model(_in_folder(path, "checkpoint", "m.json")
                                                                 .with_suffix(".safetensors"))
    return files


def _in_folder(path: Path, folder: str, name: str) -> Path:
    """``path``'s bytes as ``name`` in ``folder`` beside it (an OpenPose frame, a checkpoint's JSON)."""
    target = path.parent / folder / name
    target.parent.mkdir(exist_ok=True)
    target.write_bytes(path.read_bytes())
    return target


def mutate(data: bytes, rng: np.random.Generator) -> bytes:
    data = bytearray(data)
    for _ in range(int(rng.integers(1, 6))):
        kind = rng.integers(0, 4)
        at = int(rng.integers(0, max(len(data), 1)))
        if kind == 0 and data:
            data[at % len(data)] = int(rng.integers(0, 256))
        elif kind == 1:
            data = data[:at]
        elif kind == 2:
            data[at:at] = data[at:at + int(rng.integers(1, 64))] * int(rng.integers(2, 20))
        else:
            data[at:at] = rng.choice(list(b'0123456789-.eE,[]{}":nul \n'), int(rng.integers(1, 12))).tobytes()
    return bytes(data)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--files", type=int, default=10000)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    outcomes, crashes = collections.Counter(), []
    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        valid = seeds(folder)
        originals = {path: path.read_bytes() for path in valid}
        paths = list(valid)
        for number in range(args.files):
            source = paths[number % len(paths)]
            target = folder / f"fuzz{source.suffix}"
            target.write_bytes(mutate(originals[source], rng))
            try:
                valid[source](target)
                outcomes["read"] += 1
            except InputError:
                outcomes["InputError"] += 1
            except Exception as err:  # the point of the benchmark: any other exception is a crash
                outcomes["crash"] += 1
                crashes.append({"format": source.name, "error": f"{type(err).__name__}: {err}"[:200]})
    summary = {"files": args.files, "seconds": round(time.perf_counter() - started, 1), **outcomes,
               "crashes": crashes[:20]}
    print(json.dumps(summary, indent=1))


if __name__ == "__main__":
    main()
