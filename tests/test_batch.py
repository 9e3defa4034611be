"""Batch jobs: the manifest's refusals, one input's task, and a whole job on a local 2-CPU Ray (outputs equal to
``ray3d lift``'s, a corrupt input reported, a second run skipping what is up to date)."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from ray3d import InputError, cameras
from ray3d.batch import read_manifest
from ray3d.batch.runner import DONE_FILE, process_entry
from ray3d.cli import main
from ray3d.demo import demo_clip

CAMERA = "h36m:S9:54138969"


def _keypoint_files(folder, count: int = 5) -> list:
    camera = cameras.h36m("S9", "54138969")
    clip = demo_clip()
    files = []
    for i in range(count):
        path = folder / f"take{i}.npz"
        np.savez(path, keypoints=camera.project(clip[i * 20:i * 20 + 40]), fps=50.0)
        files.append(path)
    return files


def _manifest(path, rows: list[dict]) -> str:
    columns = list(dict.fromkeys(k for row in rows for k in row))
    with open(path, "w", newline="") as handle:
        writer = csv.DictWriter(handle, columns)
        writer.writeheader()
        writer.writerows(rows)
    return str(path)


def test_manifest_entries_resolve_paths_and_parse_values(tmp_path):
    _keypoint_files(tmp_path, 2)
    (tmp_path / "cam.json").write_text(json.dumps(cameras.h36m("S9", "54138969").to_dict()))
    manifest = _manifest(tmp_path / "m.csv", [
        {"input": "take0.npz", "camera": "cam.json", "flip_test": "yes", "fps": "50"},
        {"input": "take1.npz", "name": "second", "camera_height": "3", "pitch": "20", "hfov": "60",
         "image_size": "1000x1000", "smooth_3d": "savgol"}])
    first, second = read_manifest(manifest)
    assert first.input == tmp_path / "take0.npz" and first.name == "take0" and first.kind == "keypoints"
    assert first.options == {"camera": str(tmp_path / "cam.json"), "flip_test": True, "fps": 50.0}
    assert second.name == "second" and second.job().cameras[0].camera().camera_height == pytest.approx(3.0)
    assert first.fingerprint() != second.fingerprint()
    json_manifest = tmp_path / "m.json"
    json_manifest.write_text(json.dumps({"inputs": [{"input": "take0.npz", "camera": CAMERA, "refine": False}]}))
    assert read_manifest(json_manifest)[0].options == {"camera": CAMERA, "refine": False}


@pytest.mark.parametrize("rows, message", [
    ([], "lists no inputs"),
    ([{"input": "take0.npz", "camera": CAMERA, "colour": "red"}], "unknown column 'colour'"),
    ([{"input": "missing.npz", "camera": CAMERA}], "missing.npz does not exist"),
    ([{"input": "take0.npz", "camera": "nowhere.json"}], "row 1: camera:"),
    ([{"input": "take0.npz"}], "no camera"),
    ([{"input": "take0.npz", "camera": CAMERA, "fps": "fast"}], "column fps: 'fast'"),
    ([{"input": "take0.npz", "camera": CAMERA, "flip_test": "maybe"}], "expected true or false"),
    ([{"input": "take0.npz", "camera": CAMERA, "detector": "people"}], "applies to video inputs"),
    ([{"input": "take0.npz", "camera": CAMERA}, {"input": "take0.npz", "camera": CAMERA}], "give one of them a name"),
    ([{"input": "take0.npz", "camera": CAMERA, "pitch": "10"}], "not both"),
])
def test_bad_manifests_are_refused_in_one_line_before_anything_starts(tmp_path, capsys, rows, message):
    _keypoint_files(tmp_path, 1)
    manifest = _manifest(tmp_path / "m.csv", rows) if rows else str(tmp_path / "m.csv")
    if not rows:
        (tmp_path / "m.csv").write_text("input,camera\n")
    with pytest.raises(InputError, match=message):
        read_manifest(manifest)
    assert main(["batch", manifest, "--out", str(tmp_path / "out")]) == 2
    error = capsys.readouterr().err.strip()
    assert len(error.splitlines()) == 1 and message.split(":")[0].strip("'") in error
    assert not (tmp_path / "out").exists()


def test_a_missing_manifest_is_refused(tmp_path, capsys):
    assert main(["batch", str(tmp_path / "none.csv"), "--out", str(tmp_path / "out")]) == 2
    assert "no such manifest" in capsys.readouterr().err


def test_one_task_writes_in_place_atomically_and_reports_a_bad_input(tmp_path):
    files = _keypoint_files(tmp_path, 1)
    (tmp_path / "bad.npz").write_bytes(b"not a zip")
    manifest = _manifest(tmp_path / "m.csv", [{"input": "take0.npz", "camera": CAMERA},
                                              {"input": "bad.npz", "camera": CAMERA}])
    good, bad = read_manifest(manifest)
    out = tmp_path / "out"
    out.mkdir()
    summary = process_entry(good, out, "abc")
    assert summary["status"] == "done" and summary["frames"] == 40 and summary["people"] == 1
    assert json.loads((out / "take0" / DONE_FILE).read_text())["fingerprint"] == "abc"
    assert (out / "take0" / "world.json").is_file()
    again = process_entry(good, out, "def")  # a changed entry replaces its older output
    assert again["status"] == "done" and json.loads((out / "take0" / DONE_FILE).read_text())["fingerprint"] == "def"
    failed = process_entry(bad, out, "ghi")
    assert failed["status"] == "failed" and "not an npz file" in failed["error"]
    assert sorted(p.name for p in out.iterdir()) == ["take0"]  # no temporary folder left behind
    assert files[0].is_file()


def test_a_job_on_a_local_two_cpu_ray_equals_ray3d_lift_and_resumes(tmp_path, capsys):
    ray = pytest.importorskip("ray", reason="the cluster extra is not installed: pip install 'ray3d[cluster]'")
    files = _keypoint_files(tmp_path, 5)
    (tmp_path / "take5.npz").write_bytes(b"corrupt: not an npz")
    rows = [{"input": f"take{i}.npz", "camera": CAMERA} for i in range(6)]
    manifest = _manifest(tmp_path / "m.csv", rows)
    out = tmp_path / "out"
    assert main(["batch", manifest, "--out", str(out), "--workers", "2"]) == 1
    captured = capsys.readouterr()
    assert "1 of 6 inputs failed" in captured.err and "take5" in captured.err
    assert not ray.is_initialized()  # the job stopped the Ray it started
    for path in files:
        reference = tmp_path / f"{path.stem}-lift.json"
        assert main(["lift", "--keypoints", str(path), "--camera", CAMERA, "--out", str(reference)]) == 0
        assert (out / path.stem / "world.json").read_bytes() == reference.read_bytes()
    with open(out / "summary.csv") as handle:
        summary = {row["name"]: row for row in csv.DictReader(handle)}
    assert [summary[f"take{i}"]["status"] for i in range(6)] == ["done"] * 5 + ["failed"]
    assert "not an npz file" in summary["take5"]["error"] and summary["take0"]["frames"] == "40"
    capsys.readouterr()

    # Run again with one entry changed: that one is made again, the other four skipped, the corrupt one fails.
    rows[1]["flip_test"] = "true"
    manifest = _manifest(tmp_path / "m.csv", rows)
    (out / ".take3.partial").mkdir()  # what a killed job leaves
    assert main(["batch", manifest, "--out", str(out), "--workers", "2"]) == 1
    assert "1 done, 4 skipped (up to date), 1 failed" in capsys.readouterr().out
    assert not (out / ".take3.partial").exists()
    assert not ray.is_initialized()


def test_a_manifest_row_may_ask_for_a_reduced_precision(tmp_path):
    from ray3d.io.world import read_world

    _keypoint_files(tmp_path, 1)
    manifest = _manifest(tmp_path / "m.csv", [{"input": "take0.npz", "camera": CAMERA, "name": "fp32"},
                                              {"input": "take0.npz", "camera": CAMERA, "name": "int8",
                                               "precision": "int8"}])
    full, reduced = read_manifest(manifest)
    assert reduced.options["precision"] == "int8" and full.fingerprint() != reduced.fingerprint()
    out = tmp_path / "out"
    out.mkdir()
    assert process_entry(full, out, "a")["status"] == process_entry(reduced, out, "b")["status"] == "done"
    joints = [read_world(out / name / "world.json").track().joints for name in ("fp32", "int8")]
    apart = np.linalg.norm(joints[0] - joints[1], axis=-1)
    assert 0 < apart.mean() < 0.02  # the int8 answer, a few millimetres from fp32's
    bad = _manifest(tmp_path / "bad.csv", [{"input": "take0.npz", "camera": CAMERA, "precision": "fp16"}])
    with pytest.raises(InputError, match="precision"):
        read_manifest(bad)


def test_a_manifest_row_takes_every_format_a_world_is_written_in(tmp_path):
    """One list of world formats: what ``ray3d video --format`` offers, a manifest accepts (the batch copy once
    lacked .bvh)."""
    from ray3d.io.world import WRITTEN_FORMATS

    _keypoint_files(tmp_path, 1)
    rows = [{"input": "take0.npz", "camera": CAMERA, "name": f"as{suffix}", "format": suffix}
            for suffix in WRITTEN_FORMATS]
    assert ".bvh" in WRITTEN_FORMATS
    assert [e.options["format"] for e in read_manifest(_manifest(tmp_path / "m.csv", rows))] == list(WRITTEN_FORMATS)
