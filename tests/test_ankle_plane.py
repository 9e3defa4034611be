"""Where the ankles meet the floor, observed from the people in view (``ray3d.refine.ankle_plane``): the estimate
from people's sizes, the camera whose z = 0 is off the floor, and what users see of it."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ray3d import Camera, Lifter
from ray3d.bench.real_video import emulated_detections
from ray3d.body import ADULT_BODY_SIZE_M, POPULATION_SIZE_SD, body_sizes, lowest_ankle_height
from ray3d.data.samples import scale_bones
from ray3d.demo import demo_clip
from ray3d.errors import InputError
from ray3d.geometry.floor import Floor, FloorRegion
from ray3d.refine.ankle_plane import (
    APPLY_CHANCE,
    PRIOR_CHANCE_OFF,
    PRIOR_SD_M,
    AnklePlane,
    PlaneObservation,
    SizeEvidence,
    decide_ankle_plane,
    given_ankle_plane,
    observe_ankle_plane,
    observe_plane,
    size_evidence,
)
from ray3d.skeleton import layout_skeleton

CONTACT, CONTACT_SD = 0.12, 0.025


def _evidence(plane: float, centre_z: float, size: float, seconds: float = 5.0) -> SizeEvidence:
    """What a person of ``size`` standing with their ankles on ``plane`` shows a camera at ``centre_z``."""
    return SizeEvidence(centre_z, float(np.log(size) - np.log(centre_z - plane)), seconds)


@pytest.mark.parametrize("centre_z", [1.1, 7.0, 12.0])
def test_people_of_the_prior_size_observe_the_plane_from_any_height(centre_z):
    """From a street camera's height as from a desk's, everybody counts and the people's own plane lies within
    its sd of where they stand: sizes tell it to a share of the drop (the population's mean size and the
    detector's are uncertain), so the higher the camera, the looser it is."""
    crowd = observe_plane([_evidence(-0.2, centre_z, ADULT_BODY_SIZE_M) for _ in range(30)], ADULT_BODY_SIZE_M)
    assert crowd.people == 30 and crowd.height_m == pytest.approx(-0.2, abs=0.01)
    shared = np.hypot(POPULATION_SIZE_SD, 0.0) * (centre_z + 0.2)
    assert crowd.sd_m >= shared and crowd.sd_m < 1.3 * shared + 0.03
    low = observe_plane([_evidence(-0.2, 1.1, ADULT_BODY_SIZE_M) for _ in range(30)], ADULT_BODY_SIZE_M)
    assert low.sd_m <= crowd.sd_m
    assert observe_plane([None, None], ADULT_BODY_SIZE_M) is None


def test_a_camera_whose_people_fit_its_floor_keeps_it_even_with_a_population_taller_than_the_prior():
    """Twenty people from a desk-high camera whose z = 0 is right: the file's floor is kept, exactly, and said
    so; so it is when the site's people are 4 % taller than the prior (which sizes cannot tell from a floor
    4 cm lower), the chance it is off then higher but under even."""
    rng = np.random.default_rng(0)
    for scale in (1.0, 1.04, 0.96):
        sizes = scale * ADULT_BODY_SIZE_M * np.exp(rng.normal(0, 0.06, 20))
        plane = observe_ankle_plane([_evidence(CONTACT, 1.2, s) for s in sizes], CONTACT, CONTACT_SD,
                                    size_source_sd=0.03)
        assert plane.decision == "kept" and plane.height_m == CONTACT and plane.floor_z_m == 0.0
        assert plane.chance_off < APPLY_CHANCE and plane.people == 20
        assert "the people fit its floor" in plane.message("desk") and plane.message("desk").endswith("nothing to do")
        # The chance it is off widens the plane's sd beyond the detector's own.
        assert plane.sd_m > CONTACT_SD


def test_people_far_off_the_files_floor_apply_theirs_and_one_person_does_not():
    rng = np.random.default_rng(1)
    sizes = ADULT_BODY_SIZE_M * np.exp(rng.normal(0, 0.06, 20))
    crowd = observe_ankle_plane([_evidence(CONTACT - 0.15, 1.1, s) for s in sizes], CONTACT, CONTACT_SD,
                                size_source_sd=0.03)
    assert crowd.decision == "applied" and crowd.chance_off > 0.7
    assert abs(crowd.height_m - (CONTACT - 0.15)) < 2 * crowd.sd_m and crowd.sd_m < 0.6 * PRIOR_SD_M
    assert crowd.floor_z_m == pytest.approx(crowd.height_m - CONTACT)
    message = crowd.message("desk")
    assert "camera desk: its z = 0 seems 0.1" in message and "above the floor" in message and "applied" in message \
        and "20 people" in message and "--lens-height" in message
    alone = observe_ankle_plane([_evidence(CONTACT - 0.15, 1.1, ADULT_BODY_SIZE_M)], CONTACT, CONTACT_SD)
    assert alone.decision == "kept" and alone.height_m == CONTACT and alone.sd_m < PRIOR_SD_M
    assert alone.observed_sd_m > crowd.observed_sd_m


def test_a_child_among_adults_is_left_out_and_nobody_keeps_the_files_floor():
    adults = [_evidence(0.12, 3.0, ADULT_BODY_SIZE_M * f) for f in (0.95, 1.0, 1.05, 0.98, 1.02, 1.0)]
    with_child = observe_plane([*adults, _evidence(0.12, 3.0, 0.6), None], ADULT_BODY_SIZE_M)
    assert with_child.people == len(adults) and abs(with_child.height_m - 0.12) < 0.05
    nobody = observe_ankle_plane([None, None], CONTACT, CONTACT_SD)
    assert (nobody.source, nobody.decision, nobody.height_m) == ("prior", "kept", CONTACT)
    assert nobody.sd_m == pytest.approx(np.sqrt((1 - PRIOR_CHANCE_OFF) * CONTACT_SD ** 2
                                                + PRIOR_CHANCE_OFF * PRIOR_SD_M ** 2))
    assert "nobody seen" in nobody.message()


def test_a_given_floor_is_applied_with_the_contact_height_on_it_and_nonsense_refused():
    plane = given_ankle_plane(-0.75, CONTACT, CONTACT_SD)
    assert plane.height_m == pytest.approx(-0.63) and plane.floor_z_m == pytest.approx(-0.75)
    assert plane.decision == "given" and plane.sd_m == CONTACT_SD and "as given" in plane.message()
    assert AnklePlane.from_summary(json.loads(json.dumps(plane.summary()))) == plane
    for bad in (float("nan"), 12.0, "low", True, None):
        with pytest.raises(InputError, match="floor_z"):
            given_ankle_plane(bad, CONTACT, CONTACT_SD)


@settings(max_examples=40, deadline=None)
@given(st.floats(0.01, 0.4), st.floats(0.0, 0.6))
def test_the_further_the_people_put_the_floor_the_likelier_it_is_off_and_a_kept_floor_stays_exact(sd, offset):
    """The chance that the file's floor is off grows with how far the people put it, in sds, either way; a kept
    floor is the file's to the last digit, an applied one lies between the file's and the people's; people who
    tell the floor no better than calibrations are off by (a street camera's crowd) never apply theirs."""
    def decided(residual: float) -> AnklePlane:
        return decide_ankle_plane(PlaneObservation(CONTACT + residual, sd, 10, 50.0, 0), CONTACT, CONTACT_SD)

    near, far = decided(offset), decided(offset + 0.05)
    assert far.chance_off >= near.chance_off - 1e-12
    assert decided(-offset).chance_off == pytest.approx(near.chance_off)
    for plane in (near, far):
        if plane.decision == "kept":
            assert plane.height_m == CONTACT and (plane.chance_off < APPLY_CHANCE or sd > PRIOR_SD_M)
        else:
            assert sd <= PRIOR_SD_M
            assert CONTACT <= plane.height_m <= plane.observed_m + 1e-12


def test_the_decisions_stated_sd_covers_the_truth_over_floors_right_and_wrong():
    """Floors drawn as the prior has them (right as often as off, off by +/- PRIOR_SD_M), people observing each to
    a spread of 0.03-0.08 m: the plane used is within 1 sd of the truth in 55-85 % of cameras, within 2 in 85 %
    or more."""
    rng = np.random.default_rng(2)
    count = 4000
    off = rng.random(count) < PRIOR_CHANCE_OFF
    truth = CONTACT + np.where(off, rng.normal(0, PRIOR_SD_M, count), rng.normal(0, CONTACT_SD, count))
    spread = rng.uniform(0.03, 0.08, count)
    seen = truth + rng.normal(0, spread)
    planes = [decide_ankle_plane(PlaneObservation(h, s, 10, 50.0, 0), CONTACT, CONTACT_SD)
              for h, s in zip(seen, spread)]
    within = np.abs(np.array([p.height_m for p in planes]) - truth) / np.array([p.sd_m for p in planes])
    assert 0.55 <= np.mean(within <= 1) <= 0.85 and np.mean(within <= 2) >= 0.85
    # Kept where right, applied where far off, mostly.
    applied = np.array([p.decision == "applied" for p in planes])
    assert np.mean(applied[~off]) < 0.2 and np.mean(applied[off & (np.abs(truth - CONTACT) > 0.15)]) > 0.8


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
    assert plane.source == "observed" and plane.decision == "applied" and plane.people >= 6
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


def test_a_camera_whose_people_fit_its_floor_keeps_it_and_lifts_them_as_with_the_floor_given(detector_lifter):
    """Ten people before a desk-high camera whose z = 0 is the floor: its floor is kept, exactly, so every person
    stands where the lift given that floor puts them; the stated sd carries the chance that it was off."""
    camera = Camera.from_height_pitch(1.2, 8.0, (1280, 720), hfov_deg=70.0)
    tracks, _ = _people_seen_by(camera, 10, seed=4)
    decided = detector_lifter.lift_tracks(tracks, camera, "coco17", 30.0)
    given = detector_lifter.lift_tracks(tracks, camera, "coco17", 30.0, floor_z=0.0)
    plane = decided.ankle_plane
    assert plane.decision == "kept" and plane.floor_z_m == 0.0 and plane.people == 10 and plane.chance_off < 0.5
    assert plane.sd_m > given.ankle_plane.sd_m
    for track in tracks:
        np.testing.assert_allclose(decided[track].joints, given[track].joints, atol=1e-9)
        assert np.all(decided[track].position_sd >= given[track].position_sd - 1e-12)


def test_one_person_alone_is_told_and_keeps_the_files_floor(detector_lifter):
    """One person cannot show a floor off beyond doubt: the lift is the one with the floor given at z = 0."""
    camera = Camera.from_height_pitch(1.2, 8.0, (1280, 720), hfov_deg=70.0)
    tracks, _ = _people_seen_by(camera, 1, seed=3)
    result = detector_lifter.lift(tracks[0][1], camera, fps=30.0, layout="coco17")
    plane = result.refinement["ankle_plane"]
    assert plane["people"] == 1 and plane["decision"] == "kept" and plane["floor_z_m"] == 0.0
    assert plane["observed_sd_m"] > 0.5 * PRIOR_SD_M and 0 < plane["chance_off"] < 0.5
    given = detector_lifter.lift(tracks[0][1], camera, fps=30.0, layout="coco17", floor_z=0.0)
    assert np.median(np.linalg.norm(result.joints - given.joints, axis=-1)) < 0.02
    unrefined = detector_lifter.lift(tracks[0][1], camera, fps=30.0, layout="coco17", refine=False)
    assert unrefined.refinement is None


def test_ray3d_lift_says_where_the_floor_was_found_and_reads_the_camera_files_floor(detector_lifter, tmp_path,
                                                                                     capsys):
    from ray3d.cli import main

    floor_camera = Camera.from_height_pitch(1.2, 8.0, (1280, 720), hfov_deg=70.0, name="desk")
    tracks, _ = _people_seen_by(floor_camera, 6)
    camera_path = tmp_path / "camera.json"
    camera_path.write_text(json.dumps(floor_camera.with_origin_at_height(0.15).to_dict()))
    keypoints = tmp_path / "people.json"
    _write_people(keypoints, tracks)
    assert main(["lift", "--keypoints", str(keypoints), "--camera", str(camera_path),
                 "--out", str(tmp_path / "w.json")]) == 0
    notes = [line for line in capsys.readouterr().err.splitlines() if "floor" in line and "people" in line]
    assert len(notes) == 1 and "camera desk: its z = 0 seems" in notes[0] and "above the floor" in notes[0] \
        and "applied" in notes[0]
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
    assert planes[0].observed_sd_m > planes[-1].observed_sd_m  # the estimate sharpens as people pass


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
    assert plane.seen_twice == 4 and "4 by two cameras at once" in plane.message()
    # The detector's planted ankle stands about 0.12 m over the floor, which lies 0.15 m below the files' z = 0.
    assert abs(plane.height_m - (0.12 - 0.15)) < 0.04 and plane.sd_m < 0.03
    assert abs(plane.height_m - (0.12 - 0.15)) < abs(sizes_alone.height_m - (0.12 - 0.15))
    # Two tracks that are not one person give nothing.
    tracks = views["front"][0]
    rays = [np.tile(front.pixels_to_world_directions(np.array([[640.0, 500.0]])), (40, 17, 1))] * 2
    assert seen_twice((front.center, side.center), (rays[0], rays[1]), (np.ones((40, 17), bool),) * 2, 30.0) is None
    assert len(tracks) == 4


def _write_people(path, tracks: dict) -> None:
    from ray3d.io.keypoints import Keypoints, write_keypoints_json

    pixels = np.concatenate([p for _, p in tracks.values()])
    ids = np.concatenate([np.full(len(f), k) for k, (f, _) in tracks.items()])
    frames = np.concatenate([f for f, _ in tracks.values()])
    seen = np.isfinite(pixels).all(-1)
    write_keypoints_json(path, Keypoints(np.nan_to_num(pixels), seen.astype(float), frames, ids, "coco17", 30.0,
                                         "test"))


def test_a_cameras_floor_is_remembered_run_after_run_beside_its_file_and_the_same_input_counts_once(tmp_path):
    """Three clips of a desk camera whose z = 0 is 0.15 m above the floor, lifted one after another: each job
    weighs in the people of the jobs before (kept beside the camera file), so the people's floor sharpens run
    after run; lifting a clip again replaces its run; without the memory nothing is kept or read."""
    from ray3d.io.floor_memory import floor_memory_path, read_floor_memory
    from ray3d.jobs import CameraChoice, Job, run_job

    floor_camera = Camera.from_height_pitch(1.2, 8.0, (1280, 720), hfov_deg=70.0, name="desk")
    camera = floor_camera.with_origin_at_height(0.15)
    camera_path = tmp_path / "desk.json"
    camera_path.write_text(json.dumps(camera.to_dict()))
    planes = []
    for k in range(3):
        tracks, _ = _people_seen_by(floor_camera, 3, seed=10 + k)
        _write_people(tmp_path / f"clip{k}.json", tracks)
        done = run_job(Job((tmp_path / f"clip{k}.json",), (CameraChoice(str(camera_path)),)), tmp_path / f"w{k}.json",
                       progress=False)
        planes.append(next(iter(done.world.tracks.values())).refinement["ankle_plane"])
    memory = floor_memory_path(camera_path)
    assert memory == tmp_path / "desk.floor.json" and len(read_floor_memory(memory, camera)) == 3
    assert [p["people"] for p in planes] == [3, 6, 9]
    assert planes[0]["observed_sd_m"] > planes[2]["observed_sd_m"]
    assert abs(planes[2]["observed_m"] - planes[2]["contact_m"] - -0.15) < 2.5 * planes[2]["observed_sd_m"]
    again = run_job(Job((tmp_path / "clip2.json",), (CameraChoice(str(camera_path)),), overwrite=True),
                    tmp_path / "w2.json", progress=False)
    assert next(iter(again.world.tracks.values())).refinement["ankle_plane"]["people"] == 9
    assert len(read_floor_memory(memory, camera)) == 3
    # A camera moved (another calibration) starts afresh; a job told to forget neither reads nor writes.
    moved = camera.with_origin_at_height(0.05)
    assert read_floor_memory(memory, moved) == []
    before = memory.read_text()
    alone = run_job(Job((tmp_path / "clip0.json",), (CameraChoice(str(camera_path)),), overwrite=True,
                        remember_floor=False), tmp_path / "w0.json", progress=False)
    assert next(iter(alone.world.tracks.values())).refinement["ankle_plane"]["people"] == 3
    assert memory.read_text() == before


def test_a_floor_memory_that_is_not_one_is_refused_naming_the_file_and_field(tmp_path):
    from ray3d.io.floor_memory import FORMAT, read_floor_memory, remember_floor

    camera = Camera.from_height_pitch(1.2, 8.0, (1280, 720), hfov_deg=70.0)
    path = tmp_path / "cam.floor.json"
    for text, field in (("{", "not a floor memory"), ('{"format": "other"}', "format"),
                        (json.dumps({"format": FORMAT, "version": 1, "runs": [{"key": "a"}]}), "runs[0]"),
                        (json.dumps({"format": FORMAT, "version": 9, "runs": []}), "version")):
        path.write_text(text)
        with pytest.raises(InputError, match=re.escape(field)) as refused:
            read_floor_memory(path, camera)
        assert str(path) in refused.value.message
    path.unlink()
    run = remember_floor(path, camera, "a", (SizeEvidence(1.1, -0.2, 3.0),), ())
    assert read_floor_memory(path, camera) == [run]


def test_a_floor_memory_that_cannot_be_written_is_said_and_the_job_stands(tmp_path, monkeypatch, capsys):
    """A camera file in a folder the user may not write: the lift is written, one note says the floor's memory
    was not kept, exit 0."""
    import ray3d.io.floor_memory as floor_memory
    from ray3d.cli import main

    def refused(*args, **kwargs):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(floor_memory, "write_text", refused)
    camera = Camera.from_height_pitch(1.2, 8.0, (1280, 720), hfov_deg=70.0, name="desk")
    (tmp_path / "desk.json").write_text(json.dumps(camera.to_dict()))
    tracks, _ = _people_seen_by(camera, 2, seed=21)
    _write_people(tmp_path / "people.json", tracks)
    assert main(["lift", "--keypoints", str(tmp_path / "people.json"), "--camera", str(tmp_path / "desk.json"),
                 "--out", str(tmp_path / "w.json")]) == 0
    notes = [line for line in capsys.readouterr().err.splitlines() if "desk.floor.json" in line]
    assert len(notes) == 1 and "Permission denied" in notes[0] and (tmp_path / "w.json").exists()
