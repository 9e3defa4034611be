"""Where the ankles meet the floor, observed from the people in view (``ray3d.refine.ankle_plane``): the estimate
from people's sizes, the camera whose z = 0 is off the floor, and what users see of it."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ray3d import Camera, Lifter
from ray3d.bench.real_video import emulated_detections
from ray3d.body import ADULT_BODY_SIZE_M, body_sizes, lowest_ankle_height
from ray3d.data.samples import scale_bones
from ray3d.demo import demo_clip
from ray3d.errors import InputError
from ray3d.geometry.floor import Floor, FloorRegion
from ray3d.refine.ankle_plane import (PRIOR_SD_M, AnklePlane, SizeEvidence, given_ankle_plane,
                                      observe_ankle_plane, size_evidence)
from ray3d.skeleton import layout_skeleton

CONTACT = 0.12


def _evidence(plane: float, centre_z: float, size: float, seconds: float = 5.0) -> SizeEvidence:
    """What a person of ``size`` standing with their ankles on ``plane`` shows a camera at ``centre_z``."""
    return SizeEvidence(centre_z, float(np.log(size) - np.log(centre_z - plane)), seconds)


@pytest.mark.parametrize("centre_z", [1.1, 7.0, 12.0])
def test_people_of_the_prior_size_place_the_plane_from_any_height(centre_z):
    """From a street camera's height as from a desk's, everybody counts and the plane lies between the prior
    and where the people stand, within its sd's reach of the latter: sizes tell it to a share of the drop (the
    population's mean size is uncertain), so the higher the camera, the looser the estimate and the more the
    prior weighs."""
    crowd = observe_ankle_plane([_evidence(-0.2, centre_z, ADULT_BODY_SIZE_M) for _ in range(30)], CONTACT)
    assert crowd.people == 30 and -0.2 < crowd.height_m < CONTACT and abs(crowd.height_m - -0.2) < 2.5 * crowd.sd_m
    low = observe_ankle_plane([_evidence(-0.2, 1.1, ADULT_BODY_SIZE_M) for _ in range(30)], CONTACT)
    assert low.sd_m <= crowd.sd_m


def test_many_people_of_the_prior_size_place_the_plane_and_one_barely_moves_it():
    rng = np.random.default_rng(0)
    sizes = ADULT_BODY_SIZE_M * np.exp(rng.normal(0, 0.06, 20))
    crowd = observe_ankle_plane([_evidence(-0.05, 1.1, s) for s in sizes], CONTACT)
    assert crowd.source == "observed" and crowd.confident and crowd.people == 20
    assert abs(crowd.height_m - -0.05) < 2 * crowd.sd_m and crowd.sd_m < 0.5 * PRIOR_SD_M
    assert crowd.floor_z_m == pytest.approx(crowd.height_m - CONTACT)
    alone = observe_ankle_plane([_evidence(-0.05, 1.1, ADULT_BODY_SIZE_M)], CONTACT)
    assert not alone.confident and crowd.sd_m < alone.sd_m < PRIOR_SD_M
    assert -0.05 < alone.height_m < CONTACT  # drawn from the prior towards what the person shows
    assert "too little to tell" in alone.message("cam") and "applied" in alone.message("cam")


def test_a_child_among_adults_is_left_out_and_nobody_gives_the_prior():
    adults = [_evidence(0.12, 3.0, ADULT_BODY_SIZE_M * f) for f in (0.95, 1.0, 1.05, 0.98, 1.02, 1.0)]
    with_child = observe_ankle_plane([*adults, _evidence(0.12, 3.0, 0.6), None], CONTACT)
    assert with_child.people == len(adults) and abs(with_child.height_m - 0.12) < 0.1
    nobody = observe_ankle_plane([None, None], CONTACT)
    assert (nobody.source, nobody.height_m, nobody.sd_m) == ("prior", CONTACT, PRIOR_SD_M)
    assert "assumed" in nobody.message()


def test_a_given_floor_is_applied_with_the_contact_height_on_it_and_nonsense_refused():
    plane = given_ankle_plane(-0.75, CONTACT)
    assert plane.height_m == pytest.approx(-0.63) and plane.floor_z_m == pytest.approx(-0.75) and plane.confident
    assert AnklePlane.from_summary(json.loads(json.dumps(plane.summary()))) == plane
    for bad in (float("nan"), 12.0, "low", True, None):
        with pytest.raises(InputError, match="floor_z"):
            given_ankle_plane(bad, CONTACT)


@settings(max_examples=30, deadline=None)
@given(st.floats(0.3, 3.0), st.floats(-0.3, 0.3))
def test_a_tracks_evidence_does_not_depend_on_the_distance_the_network_gave(scale, floor_z):
    """Sizes and the drop to the ankle grow together along the rays: scaling the pose about the camera centre
    changes nothing (the network's distance is no evidence of the plane); the plane it implies is where the feet
    stand for a person of the prior's size."""
    pose = demo_clip()[:60].astype(np.float64)
    pose = scale_bones(pose, np.full(pose.shape[:2], ADULT_BODY_SIZE_M / np.median(body_sizes(pose))))
    pose[..., 2] += floor_z
    centre = np.array([4.0, 0.5, 1.3])
    seen = np.ones(len(pose), dtype=bool)
    base = size_evidence(pose, centre, seen, 30.0)
    moved = size_evidence(centre + scale * (pose - centre), centre, seen, 30.0)
    assert moved.log_size_over_drop == pytest.approx(base.log_size_over_drop, abs=1e-9)
    lowest = np.median(lowest_ankle_height(pose))
    assert centre[2] - np.exp(base.implied_log_drop()) == pytest.approx(lowest, abs=0.05)


@settings(max_examples=25, deadline=None)
@given(st.floats(-1.0, 1.0))
def test_moving_a_cameras_origin_moves_every_z_and_nothing_else(height):
    camera = Camera.from_height_pitch(2.0, 20.0, (1280, 720), hfov_deg=70.0)
    moved = camera.with_origin_at_height(height)
    points = np.array([[3.0, 0.5, 0.1], [5.0, -1.0, 1.7]])
    np.testing.assert_allclose(moved.project(points - [0, 0, height]), camera.project(points), atol=1e-6)
    assert moved.camera_height == pytest.approx(camera.camera_height - height)
    back = moved.with_origin_at_height(-height)
    np.testing.assert_allclose(back.t, camera.t, atol=1e-12)
    region = FloorRegion("stage", np.array([[0, 0], [1, 0], [1, 1], [0, 1]]), 0.5)
    assert Floor((region,)).lowered(height).height(np.array([0.5, 0.5])) == pytest.approx(0.5 - height)


def _people_seen_by(camera: Camera, count: int, seed: int = 0) -> tuple[dict, list[np.ndarray]]:
    """``count`` walkers (the demo clip, statures drawn as adults') at places before a camera, through an
    emulated detector (COCO-17): their tracks and their true poses."""
    rng = np.random.default_rng(seed)
    clip = demo_clip()[:90:2].astype(np.float64)
    clip[..., :2] -= clip[:1, :1, :2]
    layout = layout_skeleton("coco17")
    tracks, truths = {}, []
    for k in range(count):
        pose = scale_bones(clip, np.full(clip.shape[:2], rng.normal(1.0, 0.05)))
        pose = pose + [rng.uniform(3.0, 5.0), rng.uniform(-1.0, 1.0), 0.0]
        tracks[k] = (np.arange(len(pose)), emulated_detections(pose, camera, rng, layout, 1.0))
        truths.append(pose)
    return tracks, truths


@pytest.fixture(scope="module")
def detector_lifter() -> Lifter:
    return Lifter.load(layout="coco17")


def test_people_in_view_find_a_calibration_whose_z0_is_off_the_floor(detector_lifter):
    """A camera 1.2 m over the floor given with its z = 0 0.15 m above it: eight people lifted together find
    the floor about 0.15 m below z = 0, say so, and stand nearer the truth than with the floor assumed at z = 0;
    the truth stays within the stated uncertainty's reach."""
    floor_camera = Camera.from_height_pitch(1.2, 8.0, (1280, 720), hfov_deg=70.0)
    tracks, truths = _people_seen_by(floor_camera, 8)
    given = floor_camera.with_origin_at_height(0.15)
    observed = detector_lifter.lift_tracks(tracks, given, "coco17", 30.0)
    assumed = detector_lifter.lift_tracks(tracks, given, "coco17", 30.0, floor_z=0.0)
    plane = observed.ankle_plane
    assert plane.source == "observed" and plane.people >= 6
    assert abs(plane.floor_z_m - -0.15) < 0.08 and plane.sd_m < PRIOR_SD_M
    assert assumed.ankle_plane.source == "given" and assumed.ankle_plane.floor_z_m == 0.0

    def floor_error(lifted) -> float:
        return float(np.median([np.linalg.norm(lifted[k].joints[:, 0, :2] - truth[:, 0, :2], axis=-1)
                                for k, truth in enumerate(truths)]))

    assert floor_error(observed) < 0.7 * floor_error(assumed)
    track = observed[0]
    assert track.refinement["ankle_plane"] == plane.summary()
    feet = np.nanmedian(np.array(track.refinement["frames"]["floor_height_m"], dtype=float))
    assert feet == pytest.approx(plane.floor_z_m, abs=0.05)  # the floor under the feet, in the camera's frame


def test_one_person_alone_is_told_and_never_pushed_far_from_the_prior(detector_lifter):
    camera = Camera.from_height_pitch(1.2, 8.0, (1280, 720), hfov_deg=70.0)
    tracks, _ = _people_seen_by(camera, 1, seed=3)
    result = detector_lifter.lift(tracks[0][1], camera, fps=30.0, layout="coco17")
    plane = result.refinement["ankle_plane"]
    assert plane["people"] == 1 and not plane["confident"] and plane["sd_m"] > 0.5 * PRIOR_SD_M
    assert abs(plane["floor_z_m"]) < 0.1
    unrefined = detector_lifter.lift(tracks[0][1], camera, fps=30.0, layout="coco17", refine=False)
    assert unrefined.refinement is None


def test_ray3d_lift_says_where_the_floor_was_found_and_reads_the_camera_files_floor(detector_lifter, tmp_path,
                                                                                     capsys):
    from ray3d.cli import main
    from ray3d.io.keypoints import Keypoints, write_keypoints_json

    floor_camera = Camera.from_height_pitch(1.2, 8.0, (1280, 720), hfov_deg=70.0, name="desk")
    tracks, _ = _people_seen_by(floor_camera, 6)
    camera_path = tmp_path / "camera.json"
    camera_path.write_text(json.dumps(floor_camera.with_origin_at_height(0.15).to_dict()))
    keypoints = tmp_path / "people.json"
    pixels = np.concatenate([p for _, p in tracks.values()])
    ids = np.concatenate([np.full(len(f), k) for k, (f, _) in tracks.items()])
    frames = np.concatenate([f for f, _ in tracks.values()])
    seen = np.isfinite(pixels).all(-1)
    write_keypoints_json(keypoints, Keypoints(np.nan_to_num(pixels), seen.astype(float), frames, ids, "coco17", 30.0,
                                              "test"))
    assert main(["lift", "--keypoints", str(keypoints), "--camera", str(camera_path),
                 "--out", str(tmp_path / "w.json")]) == 0
    notes = [line for line in capsys.readouterr().err.splitlines() if "ankles meet" in line]
    assert len(notes) == 1 and "below its z = 0" in notes[0] and "applied" in notes[0]
    world = json.loads((tmp_path / "w.json").read_text())
    assert world["tracks"]["0"]["refinement"]["ankle_plane"]["source"] == "observed"
    document = json.loads(camera_path.read_text())
    camera_path.write_text(json.dumps({**document, "floor_z_m": -0.15}))
    assert main(["lift", "--keypoints", str(keypoints), "--camera", str(camera_path),
                 "--out", str(tmp_path / "g.json")]) == 0
    assert "as given" in capsys.readouterr().err
    camera_path.write_text(json.dumps({**document, "floor_z_m": "low"}))
    assert main(["lift", "--keypoints", str(keypoints), "--camera", str(camera_path),
                 "--out", str(tmp_path / "b.json")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "floor_z_m" in err[0] and "camera.json" in err[0]


def test_people_lifted_one_by_one_as_live_lifts_them_reach_the_plane_of_everybody_together(detector_lifter):
    """Live lifts each track as the person leaves, with what earlier people said of the camera's ankle plane
    (``seen_before``); the last person's plane is the one of all of them lifted together."""

    camera = Camera.from_height_pitch(1.2, 8.0, (1280, 720), hfov_deg=70.0).with_origin_at_height(0.15)
    tracks, _ = _people_seen_by(camera.with_origin_at_height(-0.15), 5, seed=7)
    together = detector_lifter.lift_tracks(tracks, camera, "coco17", 30.0).ankle_plane
    seen, planes = [], []
    for track, detections in tracks.items():
        lifted = detector_lifter.lift_tracks({track: detections}, camera, "coco17", 30.0, seen_before=tuple(seen))
        seen += [e for e in lifted.evidence.values() if e is not None]
        planes.append(lifted.ankle_plane)
    assert planes[-1].height_m == pytest.approx(together.height_m, abs=1e-9)
    assert planes[-1].people == together.people
    assert planes[0].sd_m > planes[-1].sd_m  # the estimate sharpens as people pass


def test_cameras_of_one_site_share_one_floor_observed_from_all_their_people(detector_lifter):
    """Two cameras of one world frame (their z = 0 both 0.15 m above the floor) each seeing four people: one
    plane from all eight, the same in both views, and each camera's people as a lift of its own would give them
    on that plane."""
    high = Camera.from_pose([0.0, 0.0, 1.2], 0.0, np.radians(8.0), 0.0, 640.0, 640.0, 640.0, 360.0, (1280, 720))
    other = Camera.from_pose([8.0, 0.5, 1.6], np.pi, np.radians(10.0), 0.0, 640.0, 640.0, 640.0, 360.0, (1280, 720))
    views = {}
    for name, camera, seed in (("a", high, 1), ("b", other, 2)):
        tracks, _ = _people_seen_by(Camera.from_height_pitch(1.2, 8.0, (1280, 720), hfov_deg=70.0), 4, seed)
        views[name] = (tracks, camera.with_origin_at_height(0.15))
    lifted = detector_lifter.lift_cameras(views, "coco17", 30.0)
    plane = lifted["a"].ankle_plane
    assert plane == lifted["b"].ankle_plane and plane.people == sum(
        e is not None for view in lifted.values() for e in view.evidence.values())
    alone = detector_lifter.lift_tracks(*views["a"], "coco17", 30.0, floor_z=plane.floor_z_m)
    np.testing.assert_allclose(alone[0].joints, lifted["a"][0].joints, atol=1e-9)


def test_two_cameras_seeing_people_at_once_triangulate_the_plane_whatever_their_sizes(detector_lifter):
    """Two cameras of one site (z = 0 0.15 m above the floor in both files) see the same walkers at once, who are
    all a fifth smaller than the prior: sizes alone would put the floor wrong; their ankles' rays crossing put
    it where the detector's planted ankles stand."""
    from ray3d.refine.ankle_plane import seen_twice

    front = Camera.from_pose([0.0, 0.0, 1.2], 0.0, np.radians(8.0), 0.0, 640.0, 640.0, 640.0, 360.0, (1280, 720))
    side = Camera.from_pose([4.0, -4.5, 1.5], np.pi / 2, np.radians(10.0), 0.0, 640.0, 640.0, 640.0, 360.0,
                            (1280, 720))
    rng = np.random.default_rng(5)
    clip = demo_clip()[:90:2].astype(np.float64)
    clip[..., :2] -= clip[:1, :1, :2]
    layout = layout_skeleton("coco17")
    views = {"front": ({}, front.with_origin_at_height(0.15)), "side": ({}, side.with_origin_at_height(0.15))}
    for k in range(4):
        pose = scale_bones(clip, np.full(clip.shape[:2], 0.8)) + [rng.uniform(3.5, 4.5), rng.uniform(-0.5, 0.5), 0.0]
        for name, camera in (("front", front), ("side", side)):
            views[name][0][k] = (np.arange(len(pose)), emulated_detections(pose, camera, rng, layout, 1.0))
    lifted = detector_lifter.lift_cameras(views, "coco17", 30.0)
    plane = lifted["front"].ankle_plane
    sizes_alone = detector_lifter.lift_tracks(*views["front"], "coco17", 30.0).ankle_plane
    assert plane.seen_twice == 4 and "seen by two cameras at once" in plane.message()
    # The detector's planted ankle stands about 0.12 m over the floor, which lies 0.15 m below the files' z = 0.
    assert abs(plane.height_m - (0.12 - 0.15)) < 0.04 and plane.sd_m < 0.03
    assert abs(plane.height_m - (0.12 - 0.15)) < abs(sizes_alone.height_m - (0.12 - 0.15))
    # Two tracks that are not one person give nothing.
    tracks = views["front"][0]
    rays = [np.tile(front.pixels_to_world_directions(np.array([[640.0, 500.0]])), (40, 17, 1))] * 2
    assert seen_twice((front.center, side.center), (rays[0], rays[1]), (np.ones((40, 17), bool),) * 2, 30.0) is None
    assert len(tracks) == 4
