"""The Lifter API: layouts, lengths, missing joints, frame rates, tracks, chunking, smoothing."""

from __future__ import annotations

import numpy as np
import pytest

from ray3d import InputError, Lifter, cameras
from ray3d.lifting.options import LiftOptions
from ray3d.refine import RefineConfig
from ray3d.skeleton import BLAZEPOSE33, COCO17, H36M17


def _walk(frames: int) -> np.ndarray:
    rng = np.random.default_rng(0)
    pose = rng.normal(0, 0.15, (17, 3))
    pose[:, 2] += 0.9
    path = np.stack([np.linspace(-1, 1, frames), np.zeros(frames), np.zeros(frames)], -1)
    return pose[None] + path[:, None]


@pytest.fixture(scope="module")
def lifter(tiny_checkpoint):
    return Lifter.load(str(tiny_checkpoint))


@pytest.fixture(scope="module")
def camera():
    return cameras.h36m("S9", "54138969")


@pytest.mark.parametrize("frames", [1, 5, 1000])
def test_sequence_lengths(lifter, camera, frames):
    result = lifter.lift(camera.project(_walk(frames)), camera)
    assert result.joints.shape == (frames, 17, 3) and result.root.shape == (frames, 3)
    assert np.isfinite(result.joints).all() and not result.interpolated.any()
    np.testing.assert_array_equal(result.root, result.joints[:, 0])


def test_detector_layouts_lift_as_their_h36m_conversion(lifter, camera):
    from ray3d.skeleton import convert

    pixels = camera.project(_walk(20))
    for layout in (COCO17, BLAZEPOSE33):
        # A detector-layout input built from the H36M pixels (face points at the nose).
        fake = np.zeros((20, layout.num_joints, 2))
        for i, name in enumerate(layout.joint_names):
            fake[:, i] = pixels[:, H36M17.index(name)] if name in H36M17.joint_names else pixels[:, 9]
        result = lifter.lift(fake, camera, layout=layout.name)
        # The refinement expects a detector's ankle keypoint where detectors put it, higher than H36M-17's.
        detector_floor = RefineConfig.for_model(lifter.document, layout)
        converted = lifter.lift(convert(fake, layout.name), camera, refine=detector_floor)
        np.testing.assert_array_equal(result.joints, converted.joints)
        assert np.isfinite(result.joints).all()


def test_missing_joints_are_interpolated_and_reported(lifter, camera):
    pixels = camera.project(_walk(30))
    holes = pixels.copy()
    holes[10:13, 5] = np.nan
    confidences = np.ones((30, 17))
    confidences[20, 14] = 0.0
    result = lifter.lift(holes, camera, confidences=confidences)
    assert result.interpolated[10:13, 5].all() and result.interpolated[20, 14]
    assert result.interpolated.sum() == 4
    reference = lifter.lift(pixels, camera)
    assert np.abs(result.joints - reference.joints).max() < 0.05  # a straight walk interpolates well
    holes[:, 0] = np.nan
    with pytest.raises(InputError, match=r"the root \(pelvis, or both hips\) is missing in every frame"):
        lifter.lift(holes, camera)


def test_other_frame_rates_are_resampled_and_returned_at_the_input_rate(lifter, camera):
    pixels_60 = camera.project(_walk(121))
    pixels_30 = pixels_60[::2]
    result = lifter.lift(pixels_30, camera, fps=30.0, refine=False)  # the network's path (the blob is no person)
    assert result.joints.shape == (61, 17, 3) and result.fps == 30.0
    at_60 = lifter.lift(pixels_60, camera, refine=False).joints[::2]
    assert np.abs(result.joints - at_60).max() < 0.05


def test_batches_and_tracks_share_one_world(lifter, camera):
    a, b = camera.project(_walk(15)), camera.project(_walk(15) + np.array([0.5, 1.0, 0.0]))
    batch = lifter.lift(np.stack([a, b]), camera)
    assert len(batch) == 2
    tracks = lifter.lift_tracks({"left": (np.arange(15), a), "right": (np.arange(100, 115, 1), b)}, camera)
    np.testing.assert_allclose(tracks["left"].joints, batch[0].joints)
    np.testing.assert_array_equal(tracks["right"].frames, np.arange(100, 115))
    gappy = lifter.lift_tracks({7: (np.array([0, 1, 2, 5, 6]), a[[0, 1, 2, 5, 6]])}, camera)[7]
    assert len(gappy.joints) == 7 and gappy.interpolated[3:5].all()


def test_lift_tracks_is_lift_cameras_with_one_camera_and_lift_options_stand_for_the_keywords(lifter, camera):
    """One camera's people lifted by ``lift_tracks`` are ``lift_cameras``' with that one camera, to the last digit
    (their ankle plane, what they showed of the floor and the track that could not be lifted too); ``options``, a
    ``LiftOptions`` (or each camera's own), lifts as the same options given one by one."""
    rootless = camera.project(_walk(30) + np.array([-0.5, 1.0, 0.0]))
    rootless[:, 0] = np.nan
    tracks = {"a": (np.arange(30), camera.project(_walk(30))), "c": (np.arange(30), rootless),
              "b": (np.arange(10, 40), camera.project(_walk(30) + np.array([0.5, 1.0, 0.0])))}
    keywords = {"smooth_3d": "savgol", "flip_test": True, "floor_z": -0.05}
    alone = lifter.lift_tracks(tracks, camera, fps=30.0, **keywords)
    (together,) = lifter.lift_cameras({"only": (tracks, camera)}, fps=30.0, **keywords).values()
    by_options = lifter.lift_tracks(tracks, camera, fps=30.0, options=LiftOptions(**keywords))
    assert list(alone) == ["a", "b"] and list(alone.unliftable) == ["c"] and alone.ankle_plane.source == "given"
    for other in (together, by_options):
        assert list(other) == list(alone) and other.unliftable == alone.unliftable
        assert other.ankle_plane == alone.ankle_plane and other.floor_evidence() == alone.floor_evidence()
        for track, result in alone.items():
            for field in ("joints", "frames", "interpolated", "position_sd"):
                np.testing.assert_array_equal(getattr(other[track], field), getattr(result, field))
    facing = cameras.h36m("S9", "55011271")
    views = {"one": (tracks, camera), "two": ({"d": (np.arange(30), facing.project(_walk(30)))}, facing)}
    own = {"one": LiftOptions(smooth_3d=None, floor_z=-0.05),
           "two": LiftOptions(smooth_3d="savgol", flip_test=True, floor_z=-0.05)}
    given = lifter.lift_cameras(views, fps=30.0, options=own)
    spelled = lifter.lift_cameras(views, fps=30.0, smooth_3d={"one": None, "two": "savgol"},
                                  flip_test={"one": False, "two": True}, floor_z=-0.05)
    for name in views:
        assert list(given[name]) == list(spelled[name]) and given[name].ankle_plane == spelled[name].ankle_plane
        for track, result in spelled[name].items():
            np.testing.assert_array_equal(given[name][track].joints, result.joints)
    assert not np.array_equal(given["one"]["a"].joints, alone["a"].joints)  # the options did differ: no smoothing


def test_lift_with_frame_numbers_fills_the_gaps_as_lift_tracks_does(lifter, camera):
    """One person's rows with the frame number of each: the frames skipped are filled in, and the result is
    ``lift_tracks``' for the same detections; without frame numbers the rows are consecutive frames."""
    pixels = camera.project(_walk(40))
    numbers = np.array([*range(100, 112), *range(118, 140)])  # frames 112-117 missed: six frames
    rows, scores = pixels[numbers - 100], np.random.default_rng(1).uniform(0.5, 1.0, (len(numbers), 17))
    for confidences in (None, scores):
        one = lifter.lift(rows, camera, confidences, fps=30.0, frames=numbers)
        tracked = lifter.lift_tracks({5: (numbers, rows) if confidences is None else (numbers, rows, confidences)},
                                     camera, fps=30.0)[5]
        np.testing.assert_array_equal(one.frames, np.arange(100, 140))
        np.testing.assert_array_equal(one.frames, tracked.frames)
        np.testing.assert_array_equal(one.interpolated, tracked.interpolated)
        assert one.interpolated[12:18].all() and not one.interpolated[:12].any()
        np.testing.assert_allclose(one.joints, tracked.joints, rtol=0, atol=1e-9)
        np.testing.assert_allclose(one.position_sd, tracked.position_sd, rtol=0, atol=1e-9)
    unbroken = lifter.lift(rows, camera, fps=30.0)  # as before: 34 consecutive frames
    assert len(unbroken.joints) == len(rows) and not unbroken.interpolated.any()
    np.testing.assert_array_equal(unbroken.frames, np.arange(len(rows)))
    batch = lifter.lift(np.stack([rows, rows]), camera, fps=30.0, frames=np.stack([numbers, numbers]))
    np.testing.assert_array_equal(batch[1].joints, one.joints)


@pytest.mark.parametrize("frames, why", [
    (np.arange(9), "keypoints' 10 rows"),                               # one short
    (np.arange(20).reshape(10, 2), "keypoints' 10 rows"),               # not one number a row
    ([0, 1, 2, 3, 4, 5, 6, 7, 8, 8], "must increase"),                  # a frame twice
    ([0, 1, 2, 3, 4, 9, 6, 7, 8, 10], "must increase"),                 # out of order
    (np.arange(10) + 0.5, "whole numbers"),
    ([0, 1, 2, 3, 4, 5, 6, 7, 8, np.nan], "whole numbers"),
    (["a"] * 10, "not numeric"),
])
def test_lift_refuses_frame_numbers_that_are_not_one_increasing_whole_number_a_row(lifter, camera, frames, why):
    with pytest.raises(InputError, match=f"^frames: .*{why}") as refused:
        lifter.lift(camera.project(_walk(10)), camera, frames=frames)
    assert refused.value.arguments in ((), ("frames",))
    with pytest.raises(InputError, match="^frames: "):
        lifter.lift(camera.project(_walk(10))[None], camera, frames=np.arange(10))  # (B, T) for B sequences

def test_chunks_give_the_same_results(lifter, camera):
    pixels = camera.project(_walk(500))
    whole = lifter.lift(pixels, camera, chunk=10_000).joints
    # Chunks under models.inference.BATCH_PER_GROUP windows take the stacked path, which rounds differently.
    np.testing.assert_allclose(lifter.lift(pixels, camera, chunk=64).joints, whole, rtol=0, atol=1e-6)
    np.testing.assert_array_equal(lifter.lift(pixels, camera, chunk=256).joints, whole)


def test_smoothing_reduces_jitter(lifter, camera):
    rng = np.random.default_rng(3)
    pixels = camera.project(_walk(120)) + rng.normal(0, 3.0, (120, 17, 2))
    raw = lifter.lift(pixels, camera).joints
    for method in ("savgol", "one-euro"):
        smoothed = lifter.lift(pixels, camera, smooth_2d=method).joints
        assert np.abs(np.diff(smoothed, 2, axis=0)).mean() < np.abs(np.diff(raw, 2, axis=0)).mean()
    with pytest.raises(InputError, match="unknown smoothing"):
        lifter.lift(pixels, camera, smooth_3d="kalman")


def test_bad_keypoints(lifter, camera):
    with pytest.raises(InputError, match=r"expected \(frames, 17, 2\)"):
        lifter.lift(np.zeros((10, 16, 2)), camera)
    with pytest.raises(InputError, match="unknown layout"):
        lifter.lift(np.zeros((10, 17, 2)), camera, layout="openpose18")
    with pytest.raises(InputError, match="confidences: expected shape"):
        lifter.lift(camera.project(_walk(5)), camera, confidences=np.ones((5, 3)))


def test_shipped_ray3d_loads_by_default_and_beats_the_baselines_on_the_demo_clip():
    from ray3d import metrics
    from ray3d.baselines.rfrh import rfrh_root
    from ray3d.checkpoints import shipped_models
    from ray3d.demo import demo_clip

    assert {"ray3d", "videopose3d"} <= set(shipped_models())
    lifter = Lifter.load()
    assert lifter.document["model"]["name"] == "ray3d" and "HDM05" in lifter.document["trained_on"]
    camera = cameras.h36m("S9", "54138969")
    truth = demo_clip()[:120]
    pixels = camera.project(truth)
    baseline = Lifter.load("videopose3d")
    ray3d_mrpe, baseline_mrpe = (metrics.mrpe(model.lift(pixels, camera).joints, truth) for model in (lifter, baseline))
    network_mrpe, baseline_network_mrpe = (metrics.mrpe(model.lift(pixels, camera, refine=False).joints, truth)
                                           for model in (lifter, baseline))
    rfrh_mrpe = np.linalg.norm(rfrh_root(pixels[:, 0], camera) - truth[:, 0], axis=-1).mean()
    assert ray3d_mrpe < 0.25  # metres; 0.18 refined, 0.07 the network alone, when measured
    assert network_mrpe < 0.5 * baseline_network_mrpe and ray3d_mrpe < baseline_mrpe and ray3d_mrpe < 0.5 * rfrh_mrpe


def _untrained(name: str, **overrides) -> Lifter:
    import torch

    from ray3d.models import LiftingNetwork, preset

    torch.manual_seed(0)
    return Lifter(LiftingNetwork(preset(name, channels=16, hidden=32, **overrides)), {"model": name})


@pytest.mark.parametrize("name", ["ray3d-causal", "ray3d"])
@pytest.mark.parametrize("frames", [1, 3, 30])
def test_streaming_equals_offline_lifting(camera, name, frames):
    lifter = _untrained(name)
    pixels = camera.project(_walk(frames))
    stream = lifter.stream(camera)
    answers = [stream.push(p) for p in pixels]
    delay = 0 if name == "ray3d-causal" else 4
    assert all(a is None for a in answers[:delay]) and all(a is not None for a in answers[delay:])
    streamed = np.stack([a for a in answers if a is not None] + stream.flush())
    np.testing.assert_allclose(streamed, lifter.lift(pixels, camera, refine=False).joints, atol=1e-5)
    assert stream.flush() == []


def test_a_causal_stream_at_ten_frames_a_second_equals_offline_lifting_at_that_rate(camera):
    lifter = _untrained("ray3d-causal")
    pixels = camera.project(_walk(15))
    stream = lifter.stream(camera, fps=10.0)
    streamed = np.stack([stream.push(p) for p in pixels])  # an answer for every frame, at once
    np.testing.assert_allclose(streamed, lifter.lift(pixels, camera, fps=10.0, refine=False).joints, atol=1e-5)


def test_a_centred_stream_without_waiting_answers_at_once_close_to_offline_and_batches_like_one_by_one(camera):
    from ray3d.lifting.stream import lift_streams

    lifter = _untrained("ray3d")
    pixels = camera.project(_walk(20))
    stream = lifter.stream(camera, fps=10.0, wait_for_future=False)
    streamed = np.stack([stream.push(p) for p in pixels])
    offline = lifter.lift(pixels, camera, fps=10.0, refine=False).joints
    np.testing.assert_allclose(streamed[-1], offline[-1], atol=1e-5)  # the end: offline stands the future in too
    assert np.abs(streamed - offline).max() < 0.5  # elsewhere it sees 4 model frames (67 ms) less of the future
    one, two = (lifter.stream(camera, fps=10.0, wait_for_future=False) for _ in range(2))
    together = []
    for p in pixels:
        one.add(p)
        two.add(p + 5.0)
        together.append(lift_streams([one, two]))
    alone = lifter.stream(camera, fps=10.0, wait_for_future=False)
    shifted = np.stack([alone.push(p + 5.0) for p in pixels])
    np.testing.assert_allclose(np.stack([a for _, a in together]), shifted, atol=1e-5)
    np.testing.assert_allclose(np.stack([a for a, _ in together]), streamed, atol=1e-5)
    with pytest.raises(InputError, match="centred model waits for future frames only at its own 60"):
        lifter.stream(camera, fps=10.0)


def test_frames_skipped_in_a_stream_are_read_at_their_true_times(camera):
    """Every other frame pushed two frames apart answers as the whole stream does where the skipped frames lie
    halfway (the model reads its rate's frames interpolated in time either way)."""
    lifter = _untrained("ray3d-causal")
    pixels = camera.project(_walk(21))
    halfway = pixels.copy()
    halfway[1::2] = (pixels[:-1:2] + pixels[2::2]) / 2
    every = lifter.stream(camera, fps=10.0)
    whole = [every.push(p) for p in halfway]
    skipping = lifter.stream(camera, fps=10.0)
    taken = [skipping.push(p, frames_since_last=1 if k == 0 else 2) for k, p in enumerate(pixels[::2])]
    np.testing.assert_allclose(np.stack(taken), np.stack(whole[::2]), atol=1e-5)
    # Read as if the frames were next to each other, the person would walk twice as fast: not the same answer.
    hurried = lifter.stream(camera, fps=10.0)
    assert np.abs(np.stack([hurried.push(p) for p in pixels[::2]]) - np.stack(whole[::2])).max() > 1e-4
    with pytest.raises(InputError, match="frames_since_last"):
        skipping.add(pixels[0], frames_since_last=0)
    with pytest.raises(InputError, match="every frame"):
        _untrained("ray3d").stream(camera).add(pixels[0], frames_since_last=2)


def test_a_causal_model_never_looks_ahead(camera):
    lifter = _untrained("ray3d-causal")
    pixels = camera.project(_walk(40))
    changed = pixels.copy()
    changed[25:] += np.random.default_rng(0).normal(0, 30, changed[25:].shape)
    # The network; the track-level refinement smooths over the whole track and is off here.
    before, after = (lifter.lift(p, camera, refine=False).joints for p in (pixels, changed))
    np.testing.assert_array_equal(before[:25], after[:25])
    assert np.abs(before[25:] - after[25:]).max() > 1e-3


def test_streaming_holds_missing_joints_and_explains_bad_frames(camera):
    lifter = _untrained("ray3d-causal")
    pixels = camera.project(_walk(12))
    holes = pixels.copy()
    holes[5:8, 13] = np.nan                      # the left wrist: held at frame 4's position
    held = pixels.copy()
    held[5:8, 13] = pixels[4, 13]
    stream = lifter.stream(camera)
    streamed = np.stack([stream.push(p) for p in holes])
    np.testing.assert_allclose(streamed, lifter.lift(held, camera, refine=False).joints, atol=1e-5)
    first = pixels[0].copy()
    first[16] = np.nan                           # never seen yet: the right wrist takes its elbow's place
    elbow = pixels[0].copy()
    elbow[16] = pixels[0, 15]
    np.testing.assert_allclose(lifter.stream(camera).push(first), lifter.stream(camera).push(elbow), atol=1e-6)
    with pytest.raises(InputError, match=r"expected \(17, 2\)"):
        lifter.stream(camera).push(np.zeros((16, 2)))
    no_hips = pixels[0].copy()
    no_hips[[0, 1, 4]] = np.nan
    with pytest.raises(InputError, match="root"):
        lifter.stream(camera).push(no_hips)


def test_the_shipped_causal_model_answers_every_frame_at_once():
    from ray3d import metrics
    from ray3d.demo import demo_clip

    lifter = Lifter.load("ray3d-causal")
    assert lifter.model.config.causal and "HDM05" in lifter.document["trained_on"]
    camera = cameras.h36m("S9", "54138969")
    truth = demo_clip()[:120]
    pixels = camera.project(truth)
    stream = lifter.stream(camera)
    streamed = np.stack([stream.push(p) for p in pixels])  # never None: no frame waits for the future
    np.testing.assert_allclose(streamed, lifter.lift(pixels, camera, refine=False).joints, atol=1e-5)
    assert metrics.mrpe(streamed, truth) < 0.25  # metres; 0.14 when measured (docs/RESULTS.md)


def test_a_person_whose_legs_are_never_seen_is_lifted_with_flagged_legs_and_no_floor_cue(lifter, camera):
    legs = [H36M17.index(n) for n in ("r_knee", "r_ankle", "l_knee", "l_ankle")]
    pixels = camera.project(_walk(30))
    hidden = pixels.copy()
    hidden[:, legs] = np.nan
    result = lifter.lift(hidden, camera)
    assert result.interpolated[:, legs].all() and not np.delete(result.interpolated, legs, axis=1).any()
    assert np.isfinite(result.joints).all() and result.refinement["contact_fraction"] == 0.0


def test_a_track_that_cannot_be_lifted_is_reported_and_the_others_are_lifted(lifter, camera, tmp_path, capsys):
    from ray3d.cli import main
    from ray3d.io.keypoints import read_keypoints
    from ray3d.io.world import read_world

    good, legless = camera.project(_walk(20)), camera.project(_walk(20) + np.array([0.5, 1.0, 0.0]))
    legless[:, [H36M17.index("l_ankle"), H36M17.index("r_ankle")]] = np.nan  # never seen: lifted, flagged
    rootless = camera.project(_walk(20) + np.array([-0.5, 1.0, 0.0]))
    rootless[:, 0] = np.nan                                                   # never seen: cannot be placed
    path = tmp_path / "three.npz"
    np.savez(path, keypoints=np.concatenate([good, legless, rootless]), frames=np.tile(np.arange(20), 3),
             tracks=np.repeat([1, 2, 3], 20), layout="h36m17", fps=60.0)
    world = lifter.lift_keypoints(read_keypoints(path), camera)
    assert list(world.tracks) == ["1", "2"] and set(world.unliftable) == {"3"}
    assert "root" in world.unliftable["3"] and world.tracks["2"].interpolated[:, H36M17.index("l_ankle")].all()
    tracks = lifter.lift_tracks({"a": (np.arange(20), good), "b": (np.arange(20), rootless)}, camera)
    assert list(tracks) == ["a"] and list(tracks.unliftable) == ["b"]
    with pytest.raises(InputError, match="no track could be lifted: track b: .*; track c: "):
        lifter.lift_tracks({"b": (np.arange(20), rootless), "c": (np.arange(20), rootless)}, camera)
    code = main(["lift", "--keypoints", str(path), "--camera", "h36m:S9:54138969", "--out", str(tmp_path / "w.json"),
                 "--checkpoint", str(lifter.name)])
    assert code == 0 and "track 3 was not lifted" in capsys.readouterr().err
    assert list(read_world(tmp_path / "w.json").tracks) == ["1", "2"]
