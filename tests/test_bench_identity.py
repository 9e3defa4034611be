"""``ray3d bench identity``: the annotation as MOT truth, the short-track rule on maintained trackers' tracks, and
the whole benchmark on a generated two-person video (the ``trackers`` package and the video extra: skipped
without them)."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
import test_live

from ray3d.bench.identity import ANNOTATION, FIRST_DISTRACTOR, read_annotation, without_short_tracks, write_truth
from ray3d.cli import main
from ray3d.errors import InputError
from ray3d.video.detectors import Detection

CAMERA = test_live.CAMERA


def _detections(people: np.ndarray) -> dict[int, list[Detection]]:
    """{frame: a detection of each person}, as the camera sees them."""
    return {f: [Detection(p, np.ones(len(p)), 0.9) for p in frame] for f, frame in enumerate(CAMERA.project(people))}


def _video(path, people: np.ndarray):
    """The scene as a lossless video (FFV1), each person's torso in their own colour."""
    import cv2

    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"FFV1"), test_live.FPS, tuple(CAMERA.image_size))
    for image in test_live._frames(len(people), people=people):
        writer.write(np.ascontiguousarray(image[..., ::-1]))  # RGB -> BGR
    writer.release()
    return path


def test_each_annotated_box_is_a_person_and_a_detection_on_nobody_a_distractor(tmp_path):
    people = test_live._scene(3)
    by_frame = _detections(people)
    stranger = by_frame[1][0].pixels + [300.0, 0.0]  # far from both
    by_frame[1].append(Detection(stranger, np.ones(17), 0.5))
    annotated = {f: [(name, d.box) for name, d in zip("AB", found[:2])] for f, found in by_frame.items()}
    annotated[2] = annotated[2][:1]  # B not annotated in frame 2: a detection of B there counts for nobody
    people_found = write_truth(by_frame, annotated, tmp_path / "truth.txt")
    rows = [line.split(",") for line in (tmp_path / "truth.txt").read_text().splitlines()]
    assert people_found == 2
    assert sorted((int(r[0]), int(r[1]), int(r[7])) for r in rows) == [
        (1, 1, 1), (1, 2, 1), (2, 1, 1), (2, 2, 1), (2, FIRST_DISTRACTOR + 1, 8), (3, 1, 1),
        (3, FIRST_DISTRACTOR + 2, 8)]


def test_a_maintained_tracker_s_tracks_followed_under_the_shortest_are_left_out():
    found = {f: [(1, None)] + ([(2, None)] if f < 4 else []) for f in range(12)}  # 1: 12 frames, 2: 4 frames
    assert without_short_tracks(found, 10.0, 0.5) == {f: [(1, None)] for f in range(12)}
    assert without_short_tracks(found, 10.0, 0.4) == found


def test_the_shipped_annotation_is_the_whole_vtest_walk():
    annotated = read_annotation(ANNOTATION)
    assert len(annotated) == 795 and sum(map(len, annotated.values())) == 4324
    assert len({person for boxes in annotated.values() for person, _ in boxes}) == 21


def test_a_bad_annotation_is_refused_naming_its_line(tmp_path, capsys):
    bad = tmp_path / "bad.csv"
    bad.write_text("frame,person,x0,y0,x1,y1\n0,A,1,2,3,4\n1,A,1,2,three,4\n")
    assert main(["bench", "identity", str(tmp_path / "none.avi"), "--camera", "h36m:S9:54138969", "--annotation",
                 str(bad), "--out", str(tmp_path / "out")]) == 2  # the video first: there is none
    with pytest.raises(InputError, match="bad.csv line 3"):
        read_annotation(bad)


def test_the_benchmark_scores_every_tracker_on_a_two_person_video(tmp_path, capsys):
    pytest.importorskip("trackers")
    pytest.importorskip("mediapipe")
    people = test_live._scene(40)
    video = _video(tmp_path / "scene.avi", people)
    by_frame = _detections(people)
    detections = tmp_path / "detections.npz"
    np.savez_compressed(detections, frames=np.repeat(np.arange(40), 2),
                        pixels=np.stack([d.pixels for f in range(40) for d in by_frame[f]]),
                        confidences=np.ones((80, 17)), scores=np.full(80, 0.9), fps=10.0, frame_count=40,
                        layout="h36m17")
    annotation = tmp_path / "annotation.csv"
    with open(annotation, "w", newline="") as stream:
        rows = csv.writer(stream)
        rows.writerow(["frame", "person", "x0", "y0", "x1", "y1"])
        rows.writerows([f, name, *d.box] for f in range(40) for name, d in zip("AB", by_frame[f]))
    out = tmp_path / "bench"
    assert main(["bench", "identity", str(video), "--camera", "h36m:S9:54138969", "--detections", str(detections),
                 "--annotation", str(annotation), "--out", str(out)]) == 0
    scores = json.loads((out / "identities.json").read_text())
    assert scores["people"] == 2 and scores["detections"] == 80
    assert set(scores["trackers"]) == {"floor tracker + re-join", "floor tracker + re-join as it goes",
                                       "floor tracker", "ByteTrack", "OC-SORT", "SORT"}
    for ours in ("floor tracker + re-join", "floor tracker + re-join as it goes"):  # ray3d video's, ray3d live's
        found = scores["trackers"][ours]
        assert found["IDF1"] == 1.0 and found["ID switches"] == 0 and found["tracks"] == 2
    assert all(0.0 <= s["IDF1"] <= 1.0 for s in scores["trackers"].values())
    assert "| floor tracker + re-join | 1.000 | 0 |" in capsys.readouterr().out
