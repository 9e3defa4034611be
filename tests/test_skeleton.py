"""Joint layouts: structure derived from names, converters, flip."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from ray3d import InputError, skeleton
from ray3d.skeleton import BLAZEPOSE33, BODY25, COCO17, H36M14, H36M17, HUMANEVA15, LAYOUTS


def test_h36m17_matches_the_brief():
    assert H36M17.parents == (-1, 0, 1, 2, 0, 4, 5, 0, 7, 8, 9, 8, 11, 12, 8, 14, 15)
    assert H36M17.left == (4, 5, 6, 11, 12, 13)
    assert H36M17.right == (1, 2, 3, 14, 15, 16)
    assert H36M17.groups == {"torso": (0, 7, 8, 9, 10), "left_arm": (11, 12, 13), "right_arm": (14, 15, 16),
                             "left_leg": (4, 5, 6), "right_leg": (1, 2, 3)}


def test_cross_dataset_layout_is_h36m_without_spine_thorax_neck():
    points = np.arange(17 * 3, dtype=float).reshape(17, 3)
    np.testing.assert_array_equal(skeleton.convert(points, "h36m17", "h36m14"),
                                  points[[0, 1, 2, 3, 4, 5, 6, 10, 11, 12, 13, 14, 15, 16]])
    # Parents skip the dropped joints: head and shoulders hang from the pelvis.
    assert H36M14.parents[H36M14.index("head")] == 0
    assert H36M14.parents[H36M14.index("l_elbow")] == H36M14.index("l_shoulder")
    assert H36M14.groups["torso"] == (0, 7)


def test_humaneva15_to_14_uses_the_brief_indices():
    points = np.random.default_rng(0).normal(size=(5, 15, 3))
    np.testing.assert_array_equal(skeleton.convert(points, "humaneva15", "h36m14"),
                                  points[:, [0, 11, 12, 13, 8, 9, 10, 14, 2, 3, 4, 5, 6, 7]])
    assert sum(len(g) for g in HUMANEVA15.groups.values()) == 15
    with pytest.raises(InputError, match="humaneva15 has no joint 'spine'; it converts to: h36m14, humaneva15"):
        skeleton.convert(points, "humaneva15", "h36m17")


def test_3dhp_is_h36m_ordered():
    points = np.random.default_rng(0).normal(size=(2, 17, 3))
    np.testing.assert_array_equal(skeleton.convert(points, "3dhp17", "h36m17"), points)


@pytest.mark.parametrize("layout", [COCO17, BLAZEPOSE33, BODY25], ids=lambda s: s.name)
def test_face_layouts_derive_the_h36m_joints(layout):
    rng = np.random.default_rng(1)
    points = rng.normal(size=(3, layout.num_joints, 2))
    out = skeleton.convert(points, layout.name)
    get = lambda name: points[:, layout.index(name)]  # noqa: E731
    pelvis = (get("l_hip") + get("r_hip")) / 2
    thorax = (get("l_shoulder") + get("r_shoulder")) / 2
    ears = (get("l_ear") + get("r_ear")) / 2
    np.testing.assert_allclose(out[:, 0], pelvis)
    np.testing.assert_allclose(out[:, 8], thorax)
    np.testing.assert_allclose(out[:, 7], (pelvis + thorax) / 2)
    np.testing.assert_allclose(out[:, 9], get("nose"))
    np.testing.assert_allclose(out[:, 10], ears + 0.5 * (ears - thorax))
    for name in ("r_knee", "l_ankle", "l_wrist", "r_elbow", "l_shoulder", "r_hip"):
        np.testing.assert_allclose(out[:, H36M17.index(name)], get(name))


def test_confidences_of_derived_joints_are_the_least_sure_source():
    conf = np.linspace(0.1, 0.9, 17)[None]
    out = skeleton.convert_confidences(conf, "coco17")
    assert out.shape == (1, 17)
    assert out[0, 0] == pytest.approx(min(conf[0, COCO17.index("l_hip")], conf[0, COCO17.index("r_hip")]))
    assert out[0, 9] == pytest.approx(conf[0, COCO17.index("nose")])
    torch_out = skeleton.convert_confidences(torch.tensor(conf), "coco17")
    np.testing.assert_allclose(torch_out.numpy(), out)


@pytest.mark.parametrize("layout", list(LAYOUTS.values()), ids=lambda s: s.name)
def test_flip_is_an_involution_and_swaps_sides(layout):
    points = np.random.default_rng(2).normal(size=(4, layout.num_joints, 3))
    flipped = skeleton.flip(points, layout)
    np.testing.assert_array_equal(skeleton.flip(flipped, layout), points)
    for left, right in zip(layout.left, [layout.flip_permutation[i] for i in layout.left]):
        np.testing.assert_array_equal(flipped[:, left, 0], -points[:, right, 0])
        np.testing.assert_array_equal(flipped[:, left, 1:], points[:, right, 1:])
    assert len(layout.left) == len(layout.right)


def test_flip_commutes_with_conversion():
    points = torch.randn(6, 17, 3, dtype=torch.float64)
    a = skeleton.convert(skeleton.flip(points, "coco17"), "coco17")
    b = skeleton.flip(skeleton.convert(points, "coco17"), "h36m17")
    torch.testing.assert_close(a, b)


def test_bad_layout_input():
    with pytest.raises(InputError, match="unknown joint layout 'openpose'"):
        skeleton.convert(np.zeros((17, 2)), "openpose")
    with pytest.raises(InputError, match="coco17: expected 17 joints"):
        skeleton.convert(np.zeros((5, 18, 2)), "coco17")
    with pytest.raises(InputError, match="h36m17 has 17 joints"):
        skeleton.flip(np.zeros((5, 16, 3)))


def test_17_joint_layouts_are_told_apart_by_their_geometry():
    from ray3d import cameras
    from ray3d.demo import demo_clip
    from ray3d.skeleton import identify_17_joint_layout

    camera = cameras.h36m("S9", "55011271")
    h36m = camera.project(demo_clip()[::10])
    assert identify_17_joint_layout(h36m) == "h36m17"
    coco = h36m[:, [H36M17.index(n) if n in H36M17.joint_names else H36M17.index("neck_nose")
                    for n in COCO17.joint_names]]
    coco[:, 1:5] += np.array([[4.0, -3], [-4, -3], [9, 0], [-9, 0]])  # eyes and ears around the nose
    assert identify_17_joint_layout(coco) == "coco17"
    assert identify_17_joint_layout(np.full((3, 17, 2), np.nan)) is None
