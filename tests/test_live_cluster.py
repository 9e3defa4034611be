"""Live on Ray (``ray3d.live.cluster``): each camera in a Ray actor on a local 2-CPU Ray gives the world the
in-process run gives; a camera actor killed mid-stream is started again and its stream goes on, the events before
and after written; SIGTERM during a Ray run ends it with every output complete and no Ray process left."""

from __future__ import annotations

import functools
import json
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("ray")

import ray  # noqa: E402
import ray.cloudpickle  # noqa: E402
import test_live  # noqa: E402
from test_live import _ScriptedDetector  # noqa: E402

from ray3d.io.world import read_world  # noqa: E402
from ray3d.jobs import CameraChoice, Job  # noqa: E402
from ray3d.jobs.live import live_job, local_inputs, open_live  # noqa: E402
from ray3d.lifting.options import VideoOptions  # noqa: E402
from ray3d.live.runner import LiveOptions  # noqa: E402
from ray3d.live.source import FrameSource, SourceGroup  # noqa: E402
from ray3d.metrics import match_tracks  # noqa: E402

# The scripted detector and the scene travel to the actors by value (they are test code, not importable there).
ray.cloudpickle.register_pickle_by_value(test_live)
ray.cloudpickle.register_pickle_by_value(sys.modules[__name__])

CAMERA, FPS = test_live.CAMERA, test_live.FPS


class ScriptedDetectors:
    """Makes, in the actor, a detector that finds the scene's people where its camera sees them."""

    def __init__(self, people: np.ndarray):
        self.people = people

    def __call__(self, camera):
        return _ScriptedDetector(self.people, camera)


def _video(path: Path, people: np.ndarray) -> Path:
    """The scene as a lossless video (FFV1): each frame carries its number in its first pixel."""
    import cv2

    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"FFV1"), FPS, tuple(CAMERA.image_size))
    for image in test_live._frames(len(people), people=people):
        writer.write(np.ascontiguousarray(image[..., ::-1]))  # RGB -> BGR
    writer.release()
    return path


def _job(video: Path, people: np.ndarray) -> Job:
    return Job((video,), (CameraChoice(made=CAMERA),), detector=ScriptedDetectors(people),
               video=VideoOptions(min_track_s=0.5))


OPTIONS = LiveOptions(page=False)


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    people = test_live._scene(60)
    return people, _video(tmp_path_factory.mktemp("scene") / "scene.avi", people)


def test_each_camera_in_a_ray_actor_gives_the_world_of_the_run_in_this_process(tmp_path, scene):
    people, video = scene
    job = _job(video, people)
    source = FrameSource.open(video, paced=True)
    local = live_job(job, tmp_path / "local", OPTIONS, lambda job, recorder: local_inputs(
        job, SourceGroup([source]), [CAMERA], [_ScriptedDetector(people)])).summary
    said: list[str] = []
    on_ray = live_job(job, tmp_path / "ray", OPTIONS, functools.partial(open_live, paced=True, address="local",
                                                                          workers=2), said=said.append).summary
    assert said == ["on Ray (local): 1 camera actor(s), each reading and decoding its stream, finding and lifting its "
                    "people"]
    assert not ray.is_initialized()  # the local Ray started for the run is stopped with it
    assert local.ending == on_ray.ending == "ended" and on_ray.processed + on_ray.dropped == on_ray.read == 60
    mine, theirs = read_world(local.files["world"]), read_world(on_ray.files["world"])
    assert len(mine.tracks) == len(theirs.tracks) == 2
    assert len(match_tracks(mine.tracks, theirs.tracks, within_m=0.15)) == 2  # every track matched, near
    events = [json.loads(line) for line in (tmp_path / "ray" / "events.jsonl").read_text().splitlines()]
    assert sum(e["event"] == "track started" for e in events) == sum(e["event"] == "track ended" for e in events) == 2


def test_the_camera_actors_of_a_ray_run_share_one_floor_pool_through_an_actor_of_its_own():
    """Each camera's lifts run in its own actor: the run's floor pool (``live.floor.FloorPool``) is an actor that
    every camera worker and the run's loop reach (``RemoteFloorPool``), so what one camera's people showed is in
    another camera's next lift; once the pool is gone (the run ending) it gives and takes nothing."""
    from ray3d.live.cluster import RemoteFloorPool
    from ray3d.live.floor import FloorPool
    from ray3d.refine.ankle_plane import SeenTwice, SizeEvidence

    if ray.is_initialized():
        ray.shutdown()
    ray.init(num_cpus=1, include_dashboard=False)
    try:
        pool = RemoteFloorPool(ray.remote(num_cpus=0)(FloorPool).remote())

        @ray.remote(num_cpus=0)
        def camera_lifts(pool, evidence):  # as a camera worker's Finisher: what is pooled, then its own added
            seen = pool.evidence()
            pool.add(evidence)
            return seen

        earlier, first, second = SizeEvidence(2.0, -0.2, 1.0), SizeEvidence(2.5, -0.4, 2.0), SeenTwice(0.0, 0.02, 1.0)
        pool.remember((earlier,))
        assert ray.get(camera_lifts.remote(pool, (first,))) == (earlier,)
        assert ray.get(camera_lifts.remote(pool, (second,))) == (earlier, first)
        assert pool.evidence() == (earlier, first, second)
        ray.kill(pool.actor)  # it dies a moment later: until then it may still answer
        deadline = time.monotonic() + 30
        while pool.evidence() != () and time.monotonic() < deadline:
            time.sleep(0.1)
        pool.add((first,))
        assert pool.evidence() == ()
    finally:
        ray.shutdown()


def test_a_camera_actor_killed_mid_stream_is_started_again_and_its_stream_goes_on(tmp_path, scene):
    people, video = scene
    job = _job(video, people)
    inputs = open_live(job, paced=True, address="local", workers=2)
    followed = inputs.followed
    out: dict = {}
    runner = threading.Thread(target=lambda: out.update(summary=live_job(
        job, tmp_path / "live", OPTIONS, lambda job, recorder: inputs,
        site=test_live.Site((test_live.ROOM,), (test_live.DOOR,))).summary))
    runner.start()
    deadline = time.monotonic() + 60
    while followed.workers[0].last_index < 15 and time.monotonic() < deadline:
        time.sleep(0.05)
    killed_after = followed.workers[0].last_index
    ray.kill(followed.workers[0].actor)
    runner.join(timeout=120)
    summary = out["summary"]
    assert summary.ending == "ended" and followed.workers[0].restarts == 1
    assert len(followed.dropped_stretches) == 1 and "started again" in followed.dropped_stretches[0]
    events = [json.loads(line) for line in (tmp_path / "live" / "events.jsonl").read_text().splitlines()]
    before = [e for e in events if not e["track"].startswith("r1-")]
    after = [e for e in events if e["track"].startswith("r1-")]
    assert {e["event"] for e in before} >= {"track started", "track ended"}  # those followed when it died end
    assert {e["event"] for e in after} >= {"track started", "track ended"} and after[0]["time_s"] > killed_after / FPS
    assert len(events) == summary.events
    assert read_world(summary.files["world"]).tracks  # the people followed after the restart are written


SIGTERM_SCRIPT = """
import sys, threading
sys.path.insert(0, {tests!r})
import ray.cloudpickle, test_live, test_live_cluster
ray.cloudpickle.register_pickle_by_value(test_live)
ray.cloudpickle.register_pickle_by_value(test_live_cluster)
from pathlib import Path
from ray3d.jobs.live import live_job, open_live
people = test_live._scene(400)
video = test_live_cluster._video(Path({out!r}).parent / "long.avi", people)
job = test_live_cluster._job(video, people)
def opened(job, recorder):
    inputs = open_live(job, paced=True, address="local", workers=2, recorder=recorder)
    print("started", flush=True)  # the signals are caught from the next moment on
    return inputs
run = live_job(job, {out!r}, test_live_cluster.OPTIONS, opened, signals=True)
print(run.summary.ending, run.summary.processed, flush=True)
sys.exit(128 + run.signal if run.signal else 0)
"""


def _ray_processes() -> list[str]:
    found = subprocess.run(["pgrep", "-f", "raylet|gcs_server|ray::"], capture_output=True, text=True).stdout
    return found.split()


def test_sigterm_during_a_ray_run_ends_it_with_every_output_complete_and_no_ray_left(tmp_path):
    import signal

    if ray.is_initialized():
        ray.shutdown()
    already = set(_ray_processes())
    script = tmp_path / "run.py"
    script.write_text(SIGTERM_SCRIPT.format(tests=str(Path(__file__).parent), out=str(tmp_path / "out")))
    process = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                               text=True)
    assert process.stdout.readline().strip() == "started"
    deadline = time.monotonic() + 60
    events = tmp_path / "out" / "events.jsonl"
    while (not events.exists() or events.stat().st_size == 0) and time.monotonic() < deadline:
        time.sleep(0.1)
    time.sleep(1.0)
    process.send_signal(signal.SIGTERM)
    out, err = process.communicate(timeout=120)
    assert process.returncode == 143, err
    assert out.split()[0] == "stopped"
    lines = events.read_text().splitlines()
    assert lines and all(json.loads(line)["event"] for line in lines)  # every line whole
    started = {json.loads(line)["track"] for line in lines if json.loads(line)["event"] == "track started"}
    ended = {json.loads(line)["track"] for line in lines if json.loads(line)["event"] == "track ended"}
    assert started == ended  # everybody followed was let go and said so
    assert read_world(tmp_path / "out" / "world.csv").tracks
    for _ in range(50):  # Ray's processes go within seconds of the run's end
        if not set(_ray_processes()) - already:
            break
        time.sleep(0.2)
    assert not set(_ray_processes()) - already
