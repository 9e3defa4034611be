"""BVH and ASF/AMC importers against the independent conversion of the raw files, and bad files."""

from __future__ import annotations

import numpy as np
import pytest

from ray3d import InputError
from ray3d.data.importers import import_amc, import_bvh
from ray3d.skeleton import H36M17

RIGID_BONES = [(1, 2), (2, 3), (4, 5), (5, 6), (11, 12), (12, 13), (14, 15), (15, 16)]


def _import_raw(raw, index, expected, floor=False):
    path = raw / str(expected["raw_file"][index])
    drop = int(expected["dropped_native_frames"][index])
    if path.suffix == ".amc":
        asf = raw / ("cmu_asfamc/02.asf" if "cmu" in path.parent.name else "hdm05_asfamc/HDM_bd.asf")
        return import_amc(asf, path, drop_native_frames=drop, floor=floor)
    return import_bvh(path, drop_native_frames=drop, floor=floor)


@pytest.fixture(scope="module")
def raw(mocap_dir):
    return mocap_dir / "raw"


@pytest.fixture(scope="module")
def expected(raw):
    with np.load(raw / "expected_h36m17.npz") as data:
        return {k: data[k] for k in data.files}


@pytest.mark.parametrize("index", range(4))
def test_matches_the_independent_conversion(raw, expected, index):
    clip = _import_raw(raw, index, expected)
    start, end = expected["clip_start"][index], expected["clip_start"][index + 1]
    assert clip.positions.shape == (end - start, 17, 3)
    assert np.abs(clip.positions - expected["positions"][start:end]).max() < 1e-4  # 0.1 mm
    assert clip.native_frames == expected["native_frames"][index]
    assert clip.fps == 60.0


@pytest.mark.parametrize("index", range(4))
def test_bones_are_rigid_and_the_body_stands_on_the_floor(raw, expected, index):
    clip = _import_raw(raw, index, expected, floor=True)
    for child, parent in RIGID_BONES:
        length = np.linalg.norm(clip.positions[:, child] - clip.positions[:, parent], axis=-1)
        assert length.std() < 0.005, H36M17.joint_names[child]
    lowest_ankle = clip.positions[:, [3, 6], 2].min(axis=1)
    assert -0.05 < np.percentile(lowest_ankle, 5) < 0.2
    chain = [3, 2, 1, 0, 7, 8, 9, 10]  # r_ankle up the bones to the head
    length = sum(np.linalg.norm(clip.positions[:, a] - clip.positions[:, b], axis=-1) for a, b in zip(chain, chain[1:]))
    assert 1.3 < np.median(length) < 2.0


def test_left_and_right_are_not_mirrored_on_a_walk(raw, expected):
    clip = _import_raw(raw, 0, expected)  # CMU 02_01: walk
    left_minus_right = clip.positions[:, 4] - clip.positions[:, 1]
    facing = np.cross(left_minus_right, [0.0, 0.0, 1.0])[:, :2]
    travel = np.gradient(clip.positions[:, 0, :2], axis=0)
    moving = np.linalg.norm(travel, axis=-1) > 0.5 / 60  # faster than 0.5 m/s
    cosine = (facing * travel).sum(-1) / np.linalg.norm(facing, axis=-1) / np.linalg.norm(travel, axis=-1)
    assert moving.mean() > 0.5 and np.median(cosine[moving]) > 0.9


def _edit(path, tmp_path, transform):
    lines = path.read_text(encoding="latin-1").splitlines()
    target = tmp_path / path.name
    target.write_text("\n".join(transform(lines)) + "\n", encoding="latin-1")
    return target


def test_bad_bvh_files_say_what_is_wrong(raw, tmp_path):
    source = raw / "cgspeed_mb_bvh" / "02_01.bvh"
    truncated = _edit(source, tmp_path, lambda lines: lines[:-10])
    with pytest.raises(InputError, match=r"02_01.bvh: truncated: .* 343 frames but only 333"):
        import_bvh(truncated)
    header_only = _edit(source, tmp_path, lambda lines: lines[:100])
    with pytest.raises(InputError, match="truncated: no MOTION"):
        import_bvh(header_only)
    wrong_count = _edit(source, tmp_path, lambda lines: [
        text.replace("CHANNELS 3 Zrotation Yrotation Xrotation", "CHANNELS 2 Zrotation Yrotation Xrotation", 1)
        if i == 8 else text for i, text in enumerate(lines)])
    with pytest.raises(InputError, match="line 9: CHANNELS says 2 channels but lists 3"):
        import_bvh(wrong_count)
    extra_channel = _edit(source, tmp_path, lambda lines: [
        text.replace("CHANNELS 3 Zrotation Yrotation Xrotation", "CHANNELS 4 Zrotation Yrotation Xrotation Yrotation")
        if i == 8 else text for i, text in enumerate(lines)])
    with pytest.raises(InputError, match="motion rows hold .* the hierarchy declares 97 channels"):
        import_bvh(extra_channel)
    renamed = _edit(source, tmp_path, lambda lines: [text.replace("LeftUpLeg", "LeftThighBone") for text in lines])
    with pytest.raises(InputError, match="unknown joint names.*cgspeed-motionbuilder, which needs LeftUpLeg"):
        import_bvh(renamed)
    with pytest.raises(InputError, match="not a BVH file"):
        import_bvh(raw / "cmu_asfamc" / "02.asf")


def test_bad_amc_files_say_what_is_wrong(raw, tmp_path):
    asf = raw / "cmu_asfamc" / "02.asf"
    source = raw / "cmu_asfamc" / "02_01.amc"
    truncated = _edit(source, tmp_path, lambda lines: lines[:-5])
    with pytest.raises(InputError, match=r"1 frame\(s\) incomplete or truncated \(first: frame 343"):
        import_amc(asf, truncated)
    wrong_values = _edit(source, tmp_path,
                         lambda lines: [text + " 0.5" if text.startswith("lfemur") else text for text in lines])
    with pytest.raises(InputError, match="bone lfemur has 4 values, the skeleton declares 3 dofs"):
        import_amc(asf, wrong_values)
    unknown = _edit(source, tmp_path, lambda lines: [text.replace("lradius", "lulna") for text in lines])
    with pytest.raises(InputError, match="bone 'lulna' is not animated"):
        import_amc(asf, unknown)


def test_wrong_units_are_caught(raw):
    with pytest.raises(InputError, match="pass the file's units"):
        import_bvh(raw / "cgspeed_daz_bvh" / "acrnn_martial_04.bvh", units="m")
