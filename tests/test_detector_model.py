"""Detector-native models (issue 12, item 2): the joints detectors measure (``detector18``: COCO-17's and the
mid-hips) and their confidences in, H36M-17 out; face points placed on the mocap; detector-like samples; the
model picked by the keypoints' layout."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from hypothesis import given, settings
from hypothesis import strategies as st

from ray3d import InputError, Lifter, cameras
from ray3d.checkpoints import save_checkpoint
from ray3d.data.detector_emulation import FACE_POINTS, body_frames, detector_points
from ray3d.data.samples import SampleConfig, observe
from ray3d.data.virtual_cameras import sample_cameras
from ray3d.geometry import CameraBatch
from ray3d.models import LiftingNetwork, ModelConfig, TensorBatch, preset
from ray3d.models.network import predict_with_flip
from ray3d.skeleton import BLAZEPOSE33, BODY25, COCO17, DETECTOR18, DETECTOR_LAYOUTS, H36M17, HALPE26, convert, flip
from ray3d.temporal import Window

TINY = dict(channels=16, hidden=32)
DETECTOR = dict(layout="detector18", output_layout="h36m17", confidence_input=True)


def _standing(frames: int = 9, yaw: float = 0.0, rng=None) -> np.ndarray:
    """(frames, 17, 3) an H36M-17 person facing +y (turned by ``yaw``) walking along their forward direction."""
    rng = rng or np.random.default_rng(0)
    pose = np.array([[0, 0, 0.95], [-0.12, 0, 0.93], [-0.12, 0, 0.5], [-0.12, 0, 0.08], [0.12, 0, 0.93],
                     [0.12, 0, 0.5], [0.12, 0, 0.08], [0, 0, 1.2], [0, 0, 1.45], [0, 0.02, 1.55], [0, 0.02, 1.65],
                     [0.18, 0, 1.42], [0.2, 0, 1.15], [0.2, 0.05, 0.9], [-0.18, 0, 1.42], [-0.2, 0, 1.15],
                     [-0.2, 0.05, 0.9]])
    pose[:, 0] *= -1  # H36M's left joints are at +x for someone facing -y: turn them to face +y
    pose = pose + rng.normal(0, 0.005, pose.shape)
    walk = np.stack([np.zeros(frames), np.linspace(0, 0.02 * frames, frames), np.zeros(frames)], -1)
    turn = np.array([[np.cos(yaw), -np.sin(yaw), 0], [np.sin(yaw), np.cos(yaw), 0], [0, 0, 1]])
    return (pose[None] + walk[:, None]) @ turn.T


def test_detector18_is_coco17_and_the_pelvis_with_parents_first():
    assert set(DETECTOR18.joint_names) == {"pelvis", *COCO17.joint_names}
    assert DETECTOR18.joint_names[0] == "pelvis" and DETECTOR18.parents[0] == -1
    assert all(p < j for j, p in enumerate(DETECTOR18.parents) if j)
    assert all(DETECTOR18.groups[g] for g in DETECTOR18.groups)  # all five RIE groups
    permutation = np.array(DETECTOR18.flip_permutation)
    np.testing.assert_array_equal(permutation[permutation], np.arange(18))


@pytest.mark.parametrize("layout", [COCO17, HALPE26, BLAZEPOSE33, BODY25])
def test_every_detector_layout_gives_the_detector_joints_by_name(layout, rng):
    assert layout.name in DETECTOR_LAYOUTS
    pixels = rng.uniform(0, 1000, (4, layout.num_joints, 2))
    converted = convert(pixels, layout, DETECTOR18)
    for j, name in enumerate(DETECTOR18.joint_names[1:], start=1):
        np.testing.assert_array_equal(converted[:, j], pixels[:, layout.index(name)])
    np.testing.assert_allclose(converted[:, 0],
                               (pixels[:, layout.index("l_hip")] + pixels[:, layout.index("r_hip")]) / 2)
    with pytest.raises(InputError, match="cannot convert h36m17 to detector18"):
        convert(rng.uniform(0, 1, (2, 17, 2)), H36M17, DETECTOR18)


def test_face_points_sit_in_front_of_the_neck_on_their_side():
    person = _standing()
    points = detector_points(person, DETECTOR18)
    forward, left = body_frames(person)[0, :, 1], body_frames(person)[0, :, 0]
    neck = person[0, H36M17.index("neck_nose")]
    nose, l_ear, r_ear, l_eye = (points[0, DETECTOR18.index(n)] for n in ("nose", "l_ear", "r_ear", "l_eye"))
    assert (nose - neck) @ forward == pytest.approx(FACE_POINTS["nose"][1], abs=0.02)
    assert (l_ear - r_ear) @ left == pytest.approx(2 * FACE_POINTS["l_ear"][2], abs=0.02)
    assert (l_eye - neck) @ left > 0 and (l_eye - nose)[2] > 0
    for name in DETECTOR18.joint_names:  # every body joint is the mocap's own
        if name in H36M17.joint_names:
            np.testing.assert_array_equal(points[:, DETECTOR18.index(name)], person[:, H36M17.index(name)])
    np.testing.assert_array_equal(detector_points(person, H36M17), person)
    with pytest.raises(ValueError, match="no joint 'l_eye_inner'"):
        detector_points(person, BLAZEPOSE33)


@settings(max_examples=25, deadline=None)
@given(yaw=st.floats(-np.pi, np.pi), shift=st.tuples(*(st.floats(-20, 20),) * 2))
def test_face_points_turn_and_move_with_the_person(yaw, shift):
    """Equivariance: the detector joints of a turned and moved person are those of the person, turned and moved."""
    person = _standing()
    turn = np.array([[np.cos(yaw), -np.sin(yaw), 0], [np.sin(yaw), np.cos(yaw), 0], [0, 0, 1]])
    offset = np.array([*shift, 0.0])
    moved = person @ turn.T + offset
    np.testing.assert_allclose(detector_points(moved, DETECTOR18),
                               detector_points(person, DETECTOR18) @ turn.T + offset, atol=1e-9)


def _windows(count: int, rng) -> tuple[np.ndarray, CameraBatch]:
    windows = np.stack([_standing(9, rng.uniform(-np.pi, np.pi), rng) + [rng.uniform(-3, 3), rng.uniform(-3, 3), 0]
                        for _ in range(count)])
    return windows, sample_cameras(windows[:, 4, 0], rng)


def test_detector_observations_keep_the_mocap_targets(rng):
    windows, cams = _windows(64, rng)
    window = Window(9)
    h36m = observe(windows, cams, window)
    seen = observe(windows, cams, window, layout=DETECTOR18)
    assert seen.pixels.shape == (64, 9, 18, 2) and seen.confidences.shape == (64, 9, 18)
    np.testing.assert_array_equal(seen.pose, h36m.pose)
    np.testing.assert_array_equal(seen.root, h36m.root)
    assert (seen.confidences == 1).all() and seen.visible.all()  # no detector effects without a generator
    # Joints with the same name are seen at the same pixels.
    for j, name in enumerate(DETECTOR18.joint_names):
        if name in H36M17.joint_names:
            np.testing.assert_allclose(seen.pixels[..., j, :], h36m.pixels[..., H36M17.index(name), :], atol=1e-3)
    # Where a detector puts the joints (the offsets) moves what is seen, never the targets.
    offsets = observe(windows, cams, window, rng=np.random.default_rng(1), config=SampleConfig(joint_offset_m=0.05),
                      layout=DETECTOR18)
    np.testing.assert_array_equal(offsets.pose, h36m.pose)
    assert np.abs(offsets.pixels - seen.pixels).mean() > 0.1


def test_confidences_fall_as_the_noise_grows_and_are_zero_where_missed(rng):
    windows, cams = _windows(256, rng)
    config = SampleConfig(noise_height_fraction=(0.0, 0.04), noise_spread=0.5, drop_probability=0.1)
    clean = observe(windows, cams, Window(9), layout=DETECTOR18)
    batch = observe(windows, cams, Window(9), rng=np.random.default_rng(2), config=config, layout=DETECTOR18)
    assert ((batch.confidences >= 0) & (batch.confidences <= 1)).all()
    np.testing.assert_array_equal(batch.confidences[~batch.visible], 0.0)
    shown = batch.visible
    error = np.linalg.norm(batch.pixels - clean.pixels, axis=-1)[shown]
    span = np.ptp(clean.pixels[:, 4], axis=1).max(-1)[:, None, None] * np.ones(shown.shape)
    relative = error / span[shown]
    low, high = np.quantile(batch.confidences[shown], [0.25, 0.75])
    # Joints a detector is sure of are, on average, much closer to the truth than those it doubts.
    assert relative[batch.confidences[shown] >= high].mean() < 0.5 * relative[batch.confidences[shown] <= low].mean()


def test_the_output_layout_must_be_decodable_and_training_wants_h36m_outputs():
    with pytest.raises(ValueError, match="output_layout"):
        ModelConfig(layout="h36m14", output_layout="nonsense")
    config = preset("ray3d", **DETECTOR)
    assert config.input_channels == 4 and config.input_skeleton is DETECTOR18 and config.output_skeleton is H36M17
    from ray3d.train import TrainConfig

    with pytest.raises(InputError, match="H36M-17 outputs"):
        TrainConfig(model=preset("ray3d", layout="detector18"))


def _detector_network(**overrides) -> LiftingNetwork:
    torch.manual_seed(0)
    return LiftingNetwork(preset("ray3d", **{**TINY, **DETECTOR, **overrides})).eval()


def test_a_detector_network_reads_18_joints_and_their_confidences_and_predicts_17():
    model = _detector_network()
    batch = TensorBatch.example(model.receptive_field, 18, 6, seed=1)
    with torch.no_grad():
        pose, root = model(batch)
        doubted = model(TensorBatch(batch.pixels, batch.rays, batch.camera_params, batch.intrinsics, batch.roll,
                                    batch.image_width, batch.confidences * 0.1))
    assert pose.shape == (6, 17, 3) and root.shape == (6, 3)
    assert torch.all(pose[:, 0] == 0)
    assert (doubted[0] - pose).abs().max() > 1e-4  # the confidences are read
    blind = LiftingNetwork(preset("ray3d", **TINY)).eval()
    h36m = TensorBatch.example(blind.receptive_field, 17, 2, seed=1)
    with torch.no_grad():
        np.testing.assert_array_equal(blind(h36m)[0], blind(TensorBatch(
            h36m.pixels, h36m.rays, h36m.camera_params, h36m.intrinsics, h36m.roll, h36m.image_width,
            h36m.confidences * 0.1))[0])  # a model without the confidence input ignores them


def test_flip_test_mirrors_input_and_output_layouts_separately():
    """With the flip test a network is mirror-equivariant: the mirrored input gives the mirrored output, though
    input (18 joints) and output (17) flip with different permutations."""
    model = _detector_network()
    batch = TensorBatch.example(model.receptive_field, 18, 4, seed=2)
    with torch.no_grad():
        pose, root = predict_with_flip(model, model.config, batch, True)
        mirrored_pose, mirrored_root = predict_with_flip(model, model.config, batch.flipped(DETECTOR18), True)
    torch.testing.assert_close(mirrored_pose, flip(pose, H36M17), atol=1e-5, rtol=0)
    torch.testing.assert_close(mirrored_root, root * torch.tensor([-1.0, 1, 1]), atol=1e-5, rtol=0)


@pytest.fixture(scope="module")
def detector_lifter(tmp_path_factory) -> Lifter:
    model = _detector_network()
    path = tmp_path_factory.mktemp("detector_model") / "detector.safetensors"
    save_checkpoint(path, {f"model.{k}": v for k, v in model.state_dict().items()},
                    {"model": model.config, "trained_on": "nothing (untrained test model)"})
    return Lifter.load(str(path))


def _in_view(camera, frames: int) -> np.ndarray:
    """A person 5 m in front of ``camera``, on the floor."""
    spot = camera.camera_to_world(np.array([[0.0, 0.0, 5.0]]))[0] * [1, 1, 0]
    return _standing(frames) + spot


def _coco_pixels(camera, frames: int = 40) -> np.ndarray:
    return camera.project(detector_points(_in_view(camera, frames), COCO17))


def test_detector_layouts_lift_alike_and_confidences_count(detector_lifter):
    camera = cameras.h36m("S9", "54138969")
    coco = _coco_pixels(camera)
    blaze = np.full((len(coco), 33, 2), 500.0)  # BlazePose's hands and feet: not read by the detector model
    for j, name in enumerate(COCO17.joint_names):
        blaze[:, BLAZEPOSE33.index(name)] = coco[:, j]
    result = detector_lifter.lift(coco, camera, layout="coco17", refine=False)
    np.testing.assert_array_equal(detector_lifter.lift(blaze, camera, layout="blazepose33", refine=False).joints,
                                  result.joints)
    assert result.joints.shape == (40, 17, 3) and np.isfinite(result.joints).all()
    unsure = detector_lifter.lift(coco, camera, np.full((40, 17), 0.2), layout="coco17", refine=False)
    assert np.abs(unsure.joints - result.joints).max() > 1e-4
    refined = detector_lifter.lift(coco, camera, layout="coco17")
    assert np.isfinite(refined.joints).all() and refined.refinement is not None


def test_a_detector_model_refuses_h36m_keypoints_and_names_the_model_to_use(detector_lifter):
    camera = cameras.h36m("S9", "54138969")
    h36m = camera.project(_in_view(camera, 20))
    with pytest.raises(InputError, match="reads detector18 joints.*H36M-17 input such as ray3d"):
        detector_lifter.lift(h36m, camera)
    with pytest.raises(InputError, match="reads detector18"):
        detector_lifter.stream(camera)


def test_streaming_a_detector_model_equals_offline_lifting(detector_lifter):
    camera = cameras.h36m("S9", "54138969")
    coco = _coco_pixels(camera, 20)
    scores = np.random.default_rng(0).uniform(0.3, 1.0, (20, 17))
    stream = detector_lifter.stream(camera, layout="coco17")
    answers = [stream.push(p, s) for p, s in zip(coco, scores)]
    streamed = np.stack([a for a in answers if a is not None] + stream.flush())
    np.testing.assert_allclose(streamed, detector_lifter.lift(coco, camera, scores, layout="coco17",
                                                              refine=False).joints, atol=1e-5)


def test_the_shipped_detector_model_reads_coco_joints_and_confidences():
    lifter = Lifter.load("ray3d-detector")
    assert lifter.model.config.input_skeleton is DETECTOR18 and lifter.model.config.output_skeleton is H36M17
    assert lifter.model.config.confidence_input and "training performers only" in lifter.document["trained_on"]
    camera = cameras.h36m("S9", "54138969")
    person = _in_view(camera, 60)
    result = lifter.lift(camera.project(detector_points(person, COCO17)), camera, layout="coco17", fps=30)
    # Trained on real motion, it puts this synthetic walker within half a metre of where they are.
    assert np.linalg.norm(result.root - person[:, 0], axis=-1).mean() < 0.5


@pytest.mark.parametrize("backend", ["torchscript", "onnx"])
def test_backends_read_the_confidences(detector_lifter, backend):
    if backend == "onnx":
        pytest.importorskip("onnxruntime")
    from ray3d.models.backends import OnnxLiftingModel, TorchScriptLiftingModel

    network = _detector_network()
    runner = (TorchScriptLiftingModel if backend == "torchscript" else OnnxLiftingModel)(network)
    batch = TensorBatch.example(network.receptive_field, 18, 3, seed=4)
    with torch.no_grad():
        expected = network(batch)
    got = runner(batch)
    torch.testing.assert_close(got[0], expected[0], atol=1e-5, rtol=0)
    torch.testing.assert_close(got[1], expected[1], atol=1e-5, rtol=1e-6)


def test_the_real_video_bench_emulates_the_detector_a_model_reads(detector_lifter, test_motion, tiny_checkpoint):
    from ray3d.bench.real_video import emulated_detections, emulated_layout, run_emulated

    assert emulated_layout(detector_lifter) is COCO17
    camera = cameras.h36m("S9", "54138969")
    person = _in_view(camera, 200)
    pixels = emulated_detections(person, camera, np.random.default_rng(0), COCO17)
    assert pixels.shape == (200, 17, 2) and np.isnan(pixels).any()
    assert np.isfinite(pixels[:, [COCO17.index("l_hip"), COCO17.index("r_hip")]]).all()
    rows = run_emulated(detector_lifter, test_motion, pairs=1, max_frames=60)
    assert [r["refine"] for r in rows] == [False, True] and all(np.isfinite(r["mrpe_mm"]) for r in rows)
    h36m_lifter = Lifter.load(str(tiny_checkpoint))
    assert emulated_layout(h36m_lifter) is H36M17
    # An H36M-17 model can be given the COCO-17 detector too (through the conversion), for a like comparison.
    rows = run_emulated(h36m_lifter, test_motion, pairs=1, max_frames=60, layout="coco17")
    assert len(rows) == 2 and all(np.isfinite(r["mrpe_mm"]) for r in rows)
