"""``ray3d bench people``: who counts as found on known boxes, the splits of a crowd, and the whole benchmark on a
generated clip (the video extra: skipped without it)."""

from __future__ import annotations

import json

import numpy as np
import pytest
import test_live

from ray3d.bench.people import ANNOTATION, finder_named, found, read_annotation, splits
from ray3d.cli import main
from ray3d.errors import InputError
from ray3d.video.detectors import Detection


def _standing(box) -> Detection:
    """A detection whose confident keypoints span ``box`` (x0, y0, x1, y1) but for the head's top and the soles."""
    x0, y0, x1, y1 = box
    pixels = np.array([[x0, y0 + 0.06 * (y1 - y0)], [x1, y1 - 0.03 * (y1 - y0)]] * 9)[:17]
    return Detection(pixels, np.ones(17), 0.9)


def test_a_person_is_found_once_by_the_detection_that_overlaps_them():
    people = [{"box": [100, 100, 140, 200], "facing": "toward", "partly_hidden": False},
              {"box": [400, 100, 440, 200], "facing": "away", "partly_hidden": True}]
    on_first = _standing([100, 100, 140, 200])
    assert found(people, [on_first]).tolist() == [True, False]
    assert found(people, [on_first, on_first]).tolist() == [True, False]  # one detection, one person
    assert found(people, []).tolist() == [False, False]
    beside = _standing([405, 130, 425, 230])  # its centre in the second's box, too small an overlap
    assert found(people, [beside]).tolist() == [False, False]
    assert found(people, [beside], loose=True).tolist() == [False, True]


def test_each_person_s_splits_name_facing_crowding_hiding_and_height():
    people = [{"box": [100, 100, 140, 200], "facing": "toward", "partly_hidden": False},
              {"box": [120, 150, 150, 210], "facing": "profile", "partly_hidden": True},
              {"box": [400, 100, 420, 170], "facing": "away", "partly_hidden": False}]
    assert splits(people) == [["all", "facing toward", "crowded", "80-120 px"],
                              ["all", "facing profile", "crowded", "partly hidden", "0-80 px"],
                              ["all", "facing away", "apart", "0-80 px"]]


def test_the_shipped_annotation_and_a_misspelt_finder():
    annotated = read_annotation(ANNOTATION)
    assert len(annotated) == 10 and sum(map(len, annotated.values())) == 60
    with pytest.raises(InputError, match="movenet-SIZE"):
        finder_named("movenet-big")


def test_the_bench_runs_each_finder_over_a_clip(tmp_path, capsys):
    pytest.importorskip("mediapipe")
    import cv2

    people = test_live._scene(12)
    video = tmp_path / "clip.avi"
    writer = cv2.VideoWriter(str(video), cv2.VideoWriter_fourcc(*"FFV1"), test_live.FPS,
                             tuple(test_live.CAMERA.image_size))
    for image in test_live._frames(len(people), people=people):
        writer.write(np.ascontiguousarray(image[..., ::-1]))
    writer.release()
    boxes = test_live.CAMERA.project(people)
    annotation = tmp_path / "people.json"
    annotation.write_text(json.dumps({"frames": [{"frame": f, "people": [
        {"box": [*b.min(0).tolist(), *b.max(0).tolist()], "facing": "toward", "partly_hidden": False}
        for b in boxes[f]]} for f in (2, 8)]}))
    out = tmp_path / "bench"
    assert main(["bench", "people", str(video), "--camera", "h36m:S9:54138969", "--annotation", str(annotation),
                 "--finders", "none", "movenet-256", "--out", str(out)]) == 0
    rows = json.loads((out / "people.json").read_text())["rows"]
    assert [r["finder"] for r in rows] == ["none", "movenet-256"] and all(r["frames_per_s"] > 0 for r in rows)
    assert all(r["recall"]["all"][1] == 4 and 0 <= r["recall"]["all"][0] <= 4 for r in rows)  # 2 people x 2 frames
    assert main(["bench", "people", str(video), "--camera", "h36m:S9:54138969", "--finders", "blazepose",
                 "--out", str(out)]) == 2
