"""The full-frame person finder that needs no face (issue 67, item 1): MoveNet MultiPose, shipped in the package,
its output read into people in frame pixels, tiles that cover the frame, people found twice kept once."""

from __future__ import annotations

import hashlib
import importlib.util
from importlib import resources

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ray3d.errors import InputError
from ray3d.skeleton import BLAZEPOSE33, COCO17
from ray3d.video.boxes import whole_person
from ray3d.video.movenet import (
    MODEL_FILE,
    PEOPLE_PER_PASS,
    ROI_MARGIN,
    SEEN_SCORE,
    TILE_OVERLAP,
    as_blazepose,
    decode,
    input_shape,
    once_each,
    person_regions,
    tile_boxes,
)

# The float16 MoveNet MultiPose Lightning file as Google published it (TF Hub lite-model/movenet/multipose/lightning/
# tflite/float16/1, Apache-2.0), byte for byte: we ship it unchanged.
PUBLISHED_SHA256 = "d4489f89e6bd6777a8b9a1a16189832131f84ff90d82fae729e670b84d7948dd"


def test_the_shipped_model_is_the_published_file_with_its_licence():
    folder = resources.files("ray3d").joinpath("assets", "models")
    assert hashlib.sha256(folder.joinpath(MODEL_FILE).read_bytes()).hexdigest() == PUBLISHED_SHA256
    assert "Apache License" in folder.joinpath("movenet_multipose_lightning.LICENSE.txt").read_text()
    assert "MoveNet" in folder.joinpath("MODELS.md").read_text()


@settings(max_examples=60, deadline=None)
@given(width=st.integers(64, 4000), height=st.integers(64, 4000), columns=st.integers(1, 4), rows=st.integers(1, 4))
def test_tiles_are_equal_overlap_their_neighbours_by_a_quarter_and_cover_the_frame(width, height, columns, rows):
    boxes = tile_boxes(width, height, (columns, rows))
    assert boxes.shape == (columns * rows, 4)
    sizes = boxes[:, 2:] - boxes[:, :2]
    np.testing.assert_allclose(sizes - sizes[0], 0.0, atol=1e-9)
    assert boxes[:, :2].min() == 0 and np.isclose(boxes[:, 2].max(), width) and np.isclose(boxes[:, 3].max(), height)
    grid = boxes.reshape(rows, columns, 4)
    if columns > 1:
        np.testing.assert_allclose(grid[:, :-1, 2] - grid[:, 1:, 0], TILE_OVERLAP * sizes[0, 0])
    if rows > 1:
        np.testing.assert_allclose(grid[:-1, :, 3] - grid[1:, :, 1], TILE_OVERLAP * sizes[0, 1])


def test_the_input_keeps_the_aspect_in_multiples_of_32():
    assert input_shape(768, 576, 384) == (384, 288)
    assert input_shape(576, 768, 768) == (576, 768)
    assert input_shape(1920, 1080, 256) == (256, 160)  # 144 rounds half up, to 160
    assert input_shape(10, 4000, 256) == (32, 256)     # never under one stride


def _output(people: list[tuple[tuple[float, float, float, float], float]]) -> np.ndarray:
    """A (6, 56) MoveNet output: each person a box (y0, x0, y1, x1) as fractions and a score; their keypoints
    spread down the box's middle, each sure."""
    output = np.zeros((PEOPLE_PER_PASS, 56), dtype=np.float32)
    for row, ((y0, x0, y1, x1), score) in enumerate(people):
        ys = np.linspace(y0, y1, 17)
        output[row, :51] = np.column_stack([ys, np.full(17, (x0 + x1) / 2), np.full(17, 0.9)]).ravel()
        output[row, 51:] = (y0, x0, y1, x1, score)
    return output


def test_decoding_puts_people_in_frame_pixels_and_drops_the_unsure():
    origin, size = np.array([100.0, 50.0]), np.array([400.0, 300.0])
    boxes, keypoints, scores = decode(_output([((0.1, 0.2, 0.5, 0.3), 0.6), ((0.0, 0.0, 1.0, 1.0), 0.1)]), origin,
                                      size, min_score=0.15)
    assert len(boxes) == 1 and scores[0] == pytest.approx(0.6)
    np.testing.assert_allclose(boxes[0], [100 + 0.2 * 400, 50 + 0.1 * 300, 100 + 0.3 * 400, 50 + 0.5 * 300], rtol=1e-6)
    np.testing.assert_allclose(keypoints[0, 0], [100 + 0.25 * 400, 50 + 0.1 * 300, 0.9], rtol=1e-6)  # (u, v, score)
    np.testing.assert_allclose(keypoints[0, -1, :2], [100 + 0.25 * 400, 50 + 0.5 * 300], rtol=1e-6)
    empty = decode(np.zeros((PEOPLE_PER_PASS, 56)), origin, size)
    assert empty[0].shape == (0, 4) and empty[1].shape == (0, 17, 3) and empty[2].shape == (0,)


def test_a_person_found_in_two_tiles_is_kept_once_the_surer_and_neighbours_stay_apart():
    boxes = np.array([[100, 100, 140, 200],    # one person, seen by two tiles
                      [101, 102, 141, 199],
                      [150, 100, 190, 200],    # a neighbour beside them
                      [150, 100, 190, 150]])   # the neighbour's upper half, cut by a tile's edge
    keypoints = np.zeros((4, 17, 3))
    kept, _, scores = once_each(boxes.astype(float), keypoints, np.array([0.4, 0.5, 0.3, 0.35]))
    assert scores.tolist() == [0.5, 0.35] or sorted(scores.tolist()) == [0.35, 0.5]
    assert len(kept) == 2 and {tuple(b) for b in kept.astype(int)} == {(101, 102, 141, 199), (150, 100, 190, 150)}


def test_regions_hold_the_person_and_stand_a_sure_lying_body_upright():
    boxes = np.array([[100.0, 100.0, 140.0, 200.0], [300.0, 100.0, 400.0, 130.0]])
    keypoints = np.zeros((2, 17, 3))
    keypoints[0, :, 2] = 0.1                                       # unsure: upright, as a fixed camera's people
    keypoints[1, [5, 6], :] = [[310, 115, 0.9], [310, 117, 0.9]]   # shoulders left of the hips: lying
    keypoints[1, [11, 12], :] = [[370, 115, 0.9], [370, 117, 0.9]]
    regions = person_regions(boxes, keypoints)
    np.testing.assert_allclose(regions[:, :3], [[120, 150, ROI_MARGIN * 100], [350, 115, ROI_MARGIN * 100]])
    assert regions[0, 3] == 0.0
    assert abs(abs(regions[1, 3]) - np.pi / 2) < 0.05  # turned a quarter: the body's up is the crop's up
    assert person_regions(np.zeros((0, 4)), np.zeros((0, 17, 3))).shape == (0, 4)


def test_the_finders_keypoints_stand_in_blazepose_layout_seen_where_movenet_sees_them():
    keypoints = np.zeros((1, 17, 3))
    keypoints[0, :, 0], keypoints[0, :, 1] = np.arange(17) * 10.0, 100.0 + np.arange(17)
    keypoints[0, :, 2] = np.linspace(0.0, 1.0, 17)
    pixels, confidences = as_blazepose(keypoints)
    assert pixels.shape == (1, BLAZEPOSE33.num_joints, 2) and confidences.shape == (1, BLAZEPOSE33.num_joints)
    for coco, name in enumerate(COCO17.joint_names):
        np.testing.assert_allclose(pixels[0, BLAZEPOSE33.index(name)], keypoints[0, coco, :2])
    heel, ankle = BLAZEPOSE33.index("l_heel"), BLAZEPOSE33.index("l_ankle")
    np.testing.assert_allclose(pixels[0, heel], pixels[0, ankle])  # at its parent, unseen
    assert confidences[0, heel] == 0.0
    mapped = as_blazepose(np.array([[[0, 0, s]] * 17 for s in (0.0, SEEN_SCORE, 1.0)]))[1]
    np.testing.assert_allclose(mapped[:, BLAZEPOSE33.index("nose")], [0.0, 0.5, 1.0])  # seen from SEEN_SCORE on
    scores = np.linspace(0, 1, 50)
    assert np.all(np.diff(as_blazepose(np.array([[[0, 0, s]] * 17 for s in scores]))[1][:, 0]) > 0)  # monotone


def test_a_keypoint_box_grows_to_the_whole_person():
    np.testing.assert_allclose(whole_person(np.array([100.0, 200.0, 120.0, 300.0])), [98, 190, 122, 305])
    assert whole_person(np.zeros((3, 2, 4))).shape == (3, 2, 4)


needs_litert = pytest.mark.skipif(importlib.util.find_spec("ai_edge_litert") is None,
                                  reason="the video extra is not installed: pip install 'ray3d[video]'")


@needs_litert
def test_the_finder_runs_on_any_frame_and_tile_and_refuses_bad_sizes():
    from ray3d.video.movenet import MoveNetPeople

    finder = MoveNetPeople(threads=1, input_size=256, tiles=(2, 1))
    regions, scores = finder(np.full((240, 320, 3), 127, np.uint8))  # a grey frame: nobody
    assert regions.shape == (len(scores), 4) and (scores >= 0.15).all()
    regions, scores = finder(np.zeros((481, 97, 3), np.uint8))      # odd sizes: the input is resized per call
    assert regions.shape[1] == 4
    for bad in ({"input_size": 100}, {"tiles": (0, 1)}):
        with pytest.raises(InputError):
            MoveNetPeople(threads=1, **bad)


@needs_litert
def test_a_person_the_finder_sees_whose_crop_shows_the_landmark_network_nobody_is_found_by_the_finders_pose():
    """A grey frame holds nobody the landmark network can pose; a finder that saw a person there (MoveNet's output,
    scripted) makes them a detection with its own keypoints, seen where it saw them; one it saw with too few
    keypoints, or the size of no person standing there, stays out."""
    from ray3d import Camera
    from ray3d.video.detectors import PeopleDetector

    camera = Camera.from_height_pitch(3.0, 15.0, (640, 480), hfov_deg=70.0)
    foot = camera.project(np.array([[6.0, 0.0, 0.0]]))[0]
    tall = float(np.linalg.norm(camera.project(np.array([[6.0, 0.0, 1.7]]))[0] - foot))
    keypoints = np.zeros((3, 17, 3))
    for person, (shift, seen, size) in enumerate(((0.0, 0.9, 1.0), (150.0, 0.1, 1.0), (-150.0, 0.9, 4.0))):
        ys = foot[1] - size * tall * np.linspace(1.0, 0.05, 17)
        keypoints[person] = np.column_stack([np.full(17, foot[0] + shift), ys, np.full(17, seen)])
    boxes = np.concatenate([keypoints[..., :2].min(axis=1), keypoints[..., :2].max(axis=1)], axis=-1)

    class Scripted:
        def found(self, frame):
            return boxes, keypoints, np.full(3, 0.5)

    detector = PeopleDetector(camera, finder=Scripted())
    found = detector(np.full((480, 640, 3), 128, np.uint8))
    assert len(found) == 1
    nose = BLAZEPOSE33.index("nose")
    np.testing.assert_allclose(found[0].pixels[nose], keypoints[0, 0, :2])
    assert found[0].confidences[nose] > 0.5 and found[0].score == 0.5
