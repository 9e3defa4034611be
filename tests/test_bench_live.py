"""``ray3d bench live``: each mode runs the real ``ray3d live`` command line as its own process (a soak of a looped
clip with its page read, a run killed and started again on its store), on a generated few-second clip. They need
the video extra (the command's detector) and are skipped without it."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest
import test_live

from ray3d.bench.live import closing_figures
from ray3d.bench.restarts import kill_moments
from ray3d.cli import main

CAMERA = "h36m:S9:54138969"
CLIP_FRAMES = 100


@pytest.fixture(scope="module")
def clip(tmp_path_factory):
    """10 s at 10 frames/s: two people painted walking past (long enough that a kill after the models load comes
    while frames flow)."""
    pytest.importorskip("mediapipe")
    import cv2

    path = tmp_path_factory.mktemp("clip") / "clip.avi"
    people = test_live._scene(CLIP_FRAMES)
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"FFV1"), test_live.FPS,
                             tuple(test_live.CAMERA.image_size))
    for image in test_live._frames(len(people), people=people):
        writer.write(np.ascontiguousarray(image[..., ::-1]))  # RGB -> BGR
    writer.release()
    return path


def test_kills_fall_one_in_each_stretch_of_the_video_the_same_for_one_seed():
    moments = kill_moments(79.5, 5, seed=0)
    stretch = 79.5 / 6
    assert moments == sorted(moments) and len(moments) == 5
    assert all(stretch * (k - 0.3) - 0.05 <= m <= stretch * (k + 0.3) + 0.05 for k, m in enumerate(moments, 1))
    assert kill_moments(79.5, 5, seed=0) == moments != kill_moments(79.5, 5, seed=1)


def test_the_closing_line_of_ray3d_live_is_read_and_a_killed_run_says_nothing():
    said = ("store out/site.db: run 1\nclip.avi: the stream ended: 28 of 60 frames processed (24 dropped, 40.0 %; 2 "
            "people left for the next frame to keep up); latency median 193 ms, 99th percentile 409 ms; 7 events; 2 "
            "people in out/world.csv (0 short tracks left out)\nstore out/site.db: run 1: 7 events, 3 positions, "
            "2 people, 0 gaps written; 3 rows lost\n")
    assert closing_figures(said) == {"read": 60, "processed": 28, "dropped": 24, "dropped_percent": 40.0,
                                     "latency_median_ms": 193.0, "latency_p99_ms": 409.0, "events": 7, "people": 2,
                                     "world": "out/world.csv", "store_rows_lost": 3}
    assert closing_figures("store out/site.db: run 1\n") == {}


def test_a_soak_loops_the_clip_reads_the_page_and_finds_every_event_stored(clip, tmp_path):
    if shutil.which("ffmpeg") is None:
        pytest.skip("ffmpeg loops the clip")
    out = tmp_path / "soak"
    assert main(["bench", "live", str(clip), "--mode", "soak", "--camera", CAMERA, "--minutes", "0.25",
                 "--out", str(out)]) == 0
    result = json.loads((out / "soak.json").read_text())
    assert (out / "looped.avi").is_file() and result["exit_code"] == 0
    assert result["read"] >= 120 and 0 < result["processed"] <= result["read"]  # 15 s of a 10 s clip, at its rate
    assert result["events_written"] == result["events_in_the_store"] == result["events"]
    assert result["snapshots_read_by_the_page_client"] > 0 and result["rss_mb_peak"] > 100
    assert main(["bench", "live", str(clip), "--mode", "soak", "--camera", CAMERA, "--out", str(out)]) == 2


def test_a_run_killed_and_started_again_on_its_store_records_nothing_twice(clip, tmp_path):
    out = tmp_path / "restarts"
    assert main(["bench", "live", str(clip), "--mode", "restarts", "--camera", CAMERA, "--kills", "1",
                 "--out", str(out)]) == 0
    result = json.loads((out / "restarts.json").read_text())
    (moment,) = kill_moments(CLIP_FRAMES / test_live.FPS, 1, 0)
    assert len(result["killed at video s"]) == 1 and result["runs"] == 2
    assert moment <= result["killed at video s"][0] < moment + 1.5  # where it was asked, within the store's commits
    assert result["gaps"][0][0] == pytest.approx(result["killed at video s"][0], abs=0.6)
    assert result["ended"] == ["cut off", "ended"] and result["duplicated"] == 0
    assert set(result["counts"]) == {"uninterrupted", "uninterrupted again", "killed and restarted"}
    recorded, tracks = result["people recorded"], result["tracks"]
    assert set(recorded) == set(tracks) and all(recorded[run] <= tracks[run] for run in tracks)  # a subset
    assert all((out / run / "site.db").is_file() for run in ("uninterrupted", "uninterrupted-again", "killed"))
