"""``ray3d bench worlds``: two world files of one scene compared track by track, on known walks."""

from __future__ import annotations

import json

import numpy as np

from ray3d import cameras
from ray3d.cli import main
from ray3d.demo import demo_clip
from ray3d.io.world import LiftResult, World, write_world

CAMERA = cameras.h36m("S9", "54138969")


def _world(path, shifts: dict[str, tuple[float, range]]):
    """A world file of the demo pose standing still at x = shift in each of its frames, one track per entry."""
    pose = demo_clip()[0] - demo_clip()[0, :1] * [1, 1, 0]
    tracks = {}
    for name, (shift, frames) in shifts.items():
        joints = np.repeat(pose[None], len(frames), axis=0) + [shift, 0.0, 0.0]
        tracks[name] = LiftResult(joints, np.zeros(joints.shape[:2], bool), 10.0, np.array(frames))
    return write_world(path, World(tracks, CAMERA, "test"))


def test_each_track_is_matched_to_the_nearest_sharing_half_its_frames(tmp_path, capsys):
    first = _world(tmp_path / "first.json", {"a": (0.0, range(0, 20)), "b": (3.0, range(20, 40))})
    second = _world(tmp_path / "second.json", {"x": (0.25, range(0, 20)), "y": (3.5, range(35, 50))})
    assert main(["bench", "worlds", str(first), str(second)]) == 0
    result = json.loads(capsys.readouterr().out)
    # a with x (0.25 m); b shares a quarter of its frames with y only: left unmatched at the default half
    assert result == {"tracks": [2, 2], "matched": 1, "median_pelvis_floor_distance_m": 0.25,
                      "largest_track_median_m": 0.25, "frames_shared": 20, "frames_first": 40}
    assert main(["bench", "worlds", str(first), str(second), "--min-share", "0.25"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["matched"] == 2 and result["largest_track_median_m"] == 0.5 and result["frames_shared"] == 25
    assert main(["bench", "worlds", str(first), str(second), "--min-share", "2"]) == 2
