"""Jobs assembled once (``ray3d.jobs``): a job's checks, its inputs lifted as the commands lift them, a batch row
with every option the command line has (a site and a floor too), the one fusion of several answers and the one
way a walk's velocity is read."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ray3d import InputError, cameras
from ray3d.batch import read_manifest
from ray3d.batch.runner import process_entry
from ray3d.demo import demo_clip
from ray3d.geometry.uncertainty import information_weighted
from ray3d.io.world import read_world
from ray3d.jobs import CameraChoice, Job, fuse_and_write, run_input, run_job
from ray3d.temporal import velocity

CAMERA = cameras.h36m("S9", "54138969")


def _keypoints(path, start: int = 0):
    np.savez(path, keypoints=CAMERA.project(demo_clip()[start:start + 40]), fps=50.0)
    return path


def test_a_job_refuses_a_camera_count_that_does_not_match_its_inputs_and_an_unknown_format(tmp_path):
    with pytest.raises(InputError, match="1 given for 2 inputs"):
        Job((tmp_path / "a.npz", tmp_path / "b.npz"), (CameraChoice("h36m:S9:54138969"),))
    with pytest.raises(InputError, match="format"):
        Job((tmp_path / "a.npz",), (CameraChoice("h36m:S9:54138969"),), world_format=".xyz")
    with pytest.raises(InputError, match="precision"):
        Job((tmp_path / "a.npz",), (CameraChoice("h36m:S9:54138969"),), precision="fp8")


def test_an_input_lifted_in_memory_is_the_one_written_and_two_cameras_fuse_into_one_person(tmp_path):
    path = _keypoints(tmp_path / "take.npz")
    job = Job((path,), (CameraChoice(made=CAMERA),))
    kept = run_input(job, 0, None, progress=False)
    written = run_input(job, 0, tmp_path / "world.json", progress=False)
    assert not kept.files and written.files == {"world": tmp_path / "world.json"} and kept.frames == 40
    on_disk = read_world(tmp_path / "world.json")
    for track, result in kept.world.tracks.items():
        np.testing.assert_allclose(on_disk.tracks[track].joints, result.joints, atol=1e-5)  # 5 decimals
    other = cameras.h36m("S9", "55011271")
    walk = demo_clip()[:200]  # long enough for the two cameras' answers to walk alike
    np.savez(tmp_path / "one.npz", keypoints=CAMERA.project(walk), fps=50.0)
    np.savez(tmp_path / "other.npz", keypoints=other.project(walk), fps=50.0)
    two = Job((tmp_path / "one.npz", tmp_path / "other.npz"), (CameraChoice(made=CAMERA), CameraChoice(made=other)))
    worlds = [run_input(two, k, None, progress=False).world for k in range(2)]
    fusion = fuse_and_write(worlds, tmp_path / "fused.json", viewer_path=tmp_path / "viewer.html")
    assert len(fusion.world.tracks) == 1 and (tmp_path / "viewer.html").exists()
    assert len(read_world(tmp_path / "fused.json").cameras) == 2
    with pytest.raises(InputError, match="exists"):  # never over an output
        fuse_and_write(worlds, tmp_path / "fused.json")


def test_a_whole_job_lifts_fuses_and_reports_with_one_model_loaded_per_layout(tmp_path):
    """``run_job``: two cameras' keypoint files -> one fused world and the site's report beside it; the job's
    model is loaded once per layout and not sent with the job to a worker; outputs and a bad site are refused
    before any work."""
    import pickle

    other = cameras.h36m("S9", "55011271")
    walk = demo_clip()[:200]
    np.savez(tmp_path / "one.npz", keypoints=CAMERA.project(walk), fps=50.0)
    np.savez(tmp_path / "other.npz", keypoints=other.project(walk), fps=50.0)
    (tmp_path / "site.json").write_text(json.dumps({"zones": [{"name": "all", "polygon": [[-9, -9], [9, -9], [9, 9],
                                                                                          [-9, 9]]}]}))
    job = Job((tmp_path / "one.npz", tmp_path / "other.npz"), (CameraChoice(made=CAMERA), CameraChoice(made=other)),
              site=tmp_path / "site.json")
    done = run_job(job, tmp_path / "out" / "world.json", progress=False)
    assert len(done.inputs) == 2 and len(done.world.tracks) == 1 and done.fusion is not None
    assert len(read_world(tmp_path / "out" / "world.json").cameras) == 2
    assert done.files == {"world": tmp_path / "out" / "world.json", "site": tmp_path / "out" / "site"}
    assert ([row["place"] for row in done.site.places] == ["all"]
            and (tmp_path / "out" / "site" / "report.html").exists())
    assert job.lifter("h36m17") is job.lifter("h36m17") is job.lifter(None) is not None
    sent = pickle.loads(pickle.dumps(job))
    assert sent._lifters == {} and (sent.inputs, sent.site) == (job.inputs, job.site) and job._lifters
    with pytest.raises(InputError, match="exists"):
        run_job(job, tmp_path / "out" / "world.json", progress=False)
    with pytest.raises(InputError, match="fused into a .json"):
        run_job(job, tmp_path / "fused.csv", progress=False)
    (tmp_path / "bad.json").write_text("{")
    with pytest.raises(InputError, match="bad.json"):
        Job((tmp_path / "one.npz",), (CameraChoice(made=CAMERA),), site=tmp_path / "bad.json")
    with pytest.raises(InputError, match="every_s"):
        Job((tmp_path / "one.npz",), (CameraChoice(made=CAMERA),), start_time=1.0)


def test_a_batch_row_takes_every_option_of_the_command_line_and_writes_its_site_report(tmp_path):
    _keypoints(tmp_path / "take.npz")
    (tmp_path / "site.json").write_text(json.dumps({"lines": [{"name": "door", "start": [-5, 0], "end": [5, 0]}]}))
    (tmp_path / "floor.json").write_text(json.dumps({"floor_regions": [
        {"name": "stage", "polygon": [[50, 50], [51, 50], [51, 51]], "height_m": 0.2}]}))
    manifest = tmp_path / "m.json"
    manifest.write_text(json.dumps([{"input": "take.npz", "camera": "h36m:S9:54138969", "site": "site.json",
                                     "floor": "floor.json", "frame": "camera", "smooth_3d": "none", "every": "0.5s",
                                     "start_time": "2026-12-05T08:00:00"}]))
    (entry,) = read_manifest(manifest)
    job = entry.job()
    assert job.floor_file == str(tmp_path / "floor.json") and job.lift.frame == "camera"
    assert job.lift_options(0).floor.regions[0].name == "stage" and job.lift.smooth_3d is None
    out = tmp_path / "out"
    out.mkdir()
    assert process_entry(entry, out, "x")["status"] == "done"
    assert read_world(out / "take" / "world.json").frame == "camera"
    assert (out / "take" / "site" / "report.html").exists() and (out / "take" / "site" / "events.jsonl").exists()
    assert "2026-12-05T08:00:00.500000" in (out / "take" / "site" / "by-time.csv").read_text()
    manifest.write_text(json.dumps([{"input": "take.npz", "camera": "h36m:S9:54138969", "site": "nowhere.json"}]))
    with pytest.raises(InputError, match="row 1: column site: .*nowhere.json does not exist"):
        read_manifest(manifest)
    manifest.write_text(json.dumps([{"input": "take.npz", "camera": "h36m:S9:54138969", "every": "soon"}]))
    with pytest.raises(InputError, match="row 1: column every: 'soon': 'soon' is not a duration"):
        read_manifest(manifest)
    manifest.write_text(json.dumps([{"input": "take.npz", "camera": "h36m:S9:54138969", "overlay": False}]))
    with pytest.raises(InputError, match="overlay applies to video inputs"):
        read_manifest(manifest)


def test_the_one_fusion_weighs_by_information_and_ignores_what_was_not_seen():
    rng = np.random.default_rng(0)
    answers = rng.normal(size=(3, 5, 3))
    same = np.broadcast_to(np.eye(3) * 0.04, (3, 5, 3, 3))
    mean, covariance = information_weighted(answers, same)
    np.testing.assert_allclose(mean, answers.mean(axis=0), atol=1e-12)
    np.testing.assert_allclose(covariance, np.broadcast_to(np.eye(3) * 0.04 / 3, (5, 3, 3)), atol=1e-12)
    seen = np.array([True, False, False])[:, None].repeat(5, axis=1)
    alone, _ = information_weighted(answers, same, seen)
    np.testing.assert_allclose(alone, answers[0], atol=1e-12)
    sure = same.copy()
    sure[1] *= 1e-6  # one far surer camera decides
    np.testing.assert_allclose(information_weighted(answers, sure)[0], answers[1], atol=1e-5)


@settings(max_examples=40, deadline=None)
@given(st.floats(-3, 3), st.floats(-3, 3), st.sampled_from([5.0, 10.0, 25.0, 30.0]), st.integers(3, 60),
       st.floats(0.1, 1.0))
def test_a_straight_walk_reads_its_own_velocity_centred_and_causal(vx, vy, fps, frames, window_s):
    times = np.arange(frames) / fps
    points = np.column_stack([vx * times, vy * times]) + [1.0, -2.0]
    for before, after in ((window_s, window_s), (window_s, 0.0)):
        moved, span = velocity(times, points, before, after)
        moving = span > 0
        np.testing.assert_allclose(moved[moving], np.broadcast_to([vx, vy], moved[moving].shape), atol=1e-9)
        assert np.all(moved[~moving] == 0) and np.all(span <= before + after + 1e-9)
    _, causal_span = velocity(times, points, window_s, 0.0)
    assert causal_span[0] == 0 and np.all(np.diff(causal_span) >= -1e-12)  # a causal window only grows, then holds


def test_each_camera_of_a_job_is_lifted_with_its_own_options_and_their_floors_must_agree(tmp_path):
    """Two keypoint files of one site: only the second camera's file says where the floor lies; that is the
    site's floor for both (it was dropped when every camera took the first's options). Two files that place
    one floor differently are refused, naming the argument."""
    other = cameras.h36m("S9", "55011271")
    walk = demo_clip()[:120]
    np.savez(tmp_path / "one.npz", keypoints=CAMERA.project(walk), fps=50.0)
    np.savez(tmp_path / "other.npz", keypoints=other.project(walk), fps=50.0)
    files = []
    for name, camera, floor_z in (("one", CAMERA, None), ("other", other, -0.1)):
        document = camera.to_dict() if floor_z is None else {**camera.to_dict(), "floor_z_m": floor_z}
        (tmp_path / f"{name}.json").write_text(json.dumps(document))
        files.append(tmp_path / f"{name}.json")
    job = Job((tmp_path / "one.npz", tmp_path / "other.npz"), tuple(CameraChoice(str(f)) for f in files))
    done = run_job(job, tmp_path / "site.json", progress=False)
    planes = [next(iter(r.world.tracks.values())).refinement["ankle_plane"] for r in done.inputs]
    assert [(p["decision"], p["floor_z_m"]) for p in planes] == [("given", -0.1), ("given", -0.1)]
    (tmp_path / "one.json").write_text(json.dumps({**CAMERA.to_dict(), "floor_z_m": 0.05}))
    with pytest.raises(InputError, match="one floor") as refused:
        run_job(job, tmp_path / "again.json", progress=False)
    assert "floor_z" in refused.value.arguments


class _NoDetector:
    """What a live camera is built with before any frame comes: the layout its detector reports."""

    layout = "h36m17"


def test_one_pair_of_camera_files_gets_the_same_floors_offline_and_live(tmp_path):
    """Two cameras of one site whose files declare different floors: the first a raised stage among its floor
    regions, the second where the floor lies (``floor_z_m``). Offline (``ray3d lift`` with both keypoint files)
    and live (the cameras a live job follows its streams with, lifting each track its camera lets go) take each
    camera's options by one rule (``Job.lift_options``): each camera on its own regions, both on the site's one
    floor height; so each person stands on the same floor both ways, to the last digit. (Live once left the first
    camera's floor height to its people.)"""
    from ray3d.jobs.live import local_inputs
    from ray3d.jobs.run import lift_cameras_together
    from ray3d.live.source import FrameSource, SourceGroup
    from ray3d.video.detectors import Detection
    from ray3d.video.track import Track

    other = cameras.h36m("S9", "55011271")
    walk = demo_clip()[:120]
    stage = {"name": "stage", "polygon": [[-1.0, -1.0], [0.05, -1.0], [0.05, 1.0], [-1.0, 1.0]], "height_m": 0.2}
    inputs, files = [], []
    for name, camera, declared in (("one", CAMERA, {"floor_regions": [stage]}), ("other", other, {"floor_z_m": -0.1})):
        np.savez(tmp_path / f"{name}.npz", keypoints=camera.project(walk), fps=50.0)
        (tmp_path / f"{name}.json").write_text(json.dumps({**camera.to_dict(), **declared}))
        inputs.append(tmp_path / f"{name}.npz")
        files.append(CameraChoice(str(tmp_path / f"{name}.json")))
    offline = lift_cameras_together(Job(tuple(inputs), tuple(files), remember_floor=False), progress=False)
    people = [next(iter(result.world.tracks.values())) for result in offline]
    assert [(p.refinement["ankle_plane"]["decision"], p.refinement["ankle_plane"]["floor_z_m"]) for p in people] == [
        ("given", -0.1), ("given", -0.1)]

    sources = [FrameSource(iter(()), 50.0, f"stream {name}", waits=True) for name in ("one", "other")]
    live_job = Job(tuple(source.name for source in sources), tuple(files), remember_floor=False)
    live = local_inputs(live_job, SourceGroup(sources), [CAMERA, other], [_NoDetector(), _NoDetector()])
    try:
        options = [view.finisher.lift_options for view in live.followed.views]
        assert [o.floor_z for o in options] == [-0.1, -0.1]
        assert [[r.name for r in o.floor.regions] for o in options] == [["stage"], []]
        for view, camera, person in zip(live.followed.views, (CAMERA, other), people):
            pixels = camera.project(walk)
            view.finisher.put(Track("0", list(range(len(walk))), [Detection(p, np.ones(17), 1.0) for p in pixels]))
            (finished,) = view.finisher.close()
            lifted = finished.world.tracks["0"]
            assert lifted.refinement["ankle_plane"] == person.refinement["ankle_plane"]
            np.testing.assert_allclose(lifted.joints, person.joints, rtol=0, atol=1e-9)
    finally:
        for view in live.followed.views:
            view.finisher.close()
        for source in sources:
            source.close()
