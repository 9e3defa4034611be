"""``ray3d bench fusion``: one test walk seen by 2-4 virtual cameras, fused offline and live (the shipped mocap:
skipped without it), and the scenes' identity-switch count on known paths."""

from __future__ import annotations

import json

import numpy as np

from ray3d.bench.fusion import FPS, identity_switches
from ray3d.cli import main


def test_a_track_counts_a_switch_only_where_it_follows_the_other_person_long_enough():
    frames = int(2 * FPS)
    people = np.zeros((2, frames, 17, 3))
    people[1, :, :, 0] = 4.0  # two people 4 m apart, standing
    roots = np.zeros((frames, 3))
    roots[30:] = [4.0, 0.0, 0.0]  # the track moves to the second person for the last second: one switch
    assert identity_switches(people, np.arange(frames), roots) == 1
    roots[33:] = 0.0  # there for 3 frames only, less than half a second: none
    assert identity_switches(people, np.arange(frames), roots) == 0


def test_the_bench_fuses_a_walk_seen_by_several_cameras_offline_and_live(mocap_dir, tmp_path):
    out = tmp_path / "fusion"
    assert main(["bench", "fusion", "--clips", "1", "--cameras", "2", "--data-dir", str(mocap_dir),
                 "--out", str(out)]) == 0
    offline = json.loads((out / "fusion.json").read_text())
    assert offline["walks"] == 1 and offline["world tracks per person (index: tracks)"] == [0, 1]  # one: no switch
    assert 0 < offline["fused abs_mpjpe mm"] < 400 and 0 < offline["best single camera abs_mpjpe mm"] < 400
    (true, found, sd), = offline["time offsets, frames (true, found, sd)"]
    assert abs(found - true) <= max(3 * sd, 2.0)
    assert offline["cam2 placed 0.5 m off: the agreement check names"] != []
    assert main(["bench", "fusion", "--live", "--clips", "1", "--cameras", "2", "--data-dir", str(mocap_dir),
                 "--out", str(out)]) == 0
    live = json.loads((out / "fusion-live.json").read_text())
    assert live["world people per person (index: people)"] == [0, 1] and live["scenes"] == 1
    assert 0 < live["fused abs_mpjpe mm"] < 500
    assert main(["bench", "fusion", "--clips", "0", "--out", str(out)]) == 2
    assert main(["bench", "fusion", "--cameras", "5", "--out", str(out)]) == 2
