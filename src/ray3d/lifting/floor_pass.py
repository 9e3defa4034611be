"""The floor-and-refinement pass over cameras' tracks (``CameraTracks``) on their way through a model's network
(``ModelRunner``): each track through the network (``run_network``), the evidence of the floor they share read and
decided (``settle``: ``refine.ankle_plane``), the network run again where the floor is not the camera's z = 0, and
each track refined on it (``refined``). What ``Lifter.lift``, ``lift_tracks`` and ``lift_cameras`` stand on."""

from __future__ import annotations

import dataclasses
import itertools

import numpy as np

from ray3d import body, temporal
from ray3d.errors import InputError
from ray3d.io.world import LiftResult
from ray3d.lifting.inputs import PreparedTrack
from ray3d.lifting.runner import ModelRunner
from ray3d.lifting.tracks import CameraTracks, people_seen_twice
from ray3d.refine import (
    AnklePlane,
    RefineConfig,
    given_ankle_plane,
    network_position_sd,
    observe_ankle_plane,
    on_observed_rays,
    refine_track,
    size_evidence,
)
from ray3d.refine.ankle_plane import SeenTwice, SizeEvidence, floor_evidence
from ray3d.skeleton import H36M17


def lift_views(runner: ModelRunner, views: list[CameraTracks], chunk: int,
               spans: list[dict] | None = None) -> tuple[list[dict], list[AnklePlane | None]]:
    """Cameras of one floor, each's tracks on their way (``CameraTracks``, with its own options), through
    ``runner``'s network -> for each {track: LiftResult, or the InputError that stopped it}, and each view's ankle
    plane (None unrefined): given (``floor_z``), or decided on every track, the evidence each view's options hold of
    people seen before (``LiftOptions.seen_before``) and, with each view's {track: frame ids} on one clock
    (``spans``), the people two cameras saw at once (``settle``). Each view's ``found`` keeps its tracks' evidence,
    and ``ankles`` the people it saw at once with another camera, of the floor itself (``floor_evidence``). The
    views are refined if the first view's options refine."""
    if isinstance(chunk, bool) or not isinstance(chunk, (int, np.integer)) or chunk < 1:
        raise InputError(f"chunk: frames per network call, a whole number of at least 1; got {chunk!r}", ("chunk",))
    for view in views:
        run_network(runner, view, 0.0, chunk)
    refine = views[0].options.refine
    configs = [refine_config(runner.document, refine, view.prepared) for view in views]
    for view, config in zip(views, configs):
        view.found = {track: None if e is None else floor_evidence(e, config.keypoint_ankle_height_m,
                                                                   config.read_size_m)
                      for track, e in view.found.items()}
    if not refine or not any(view.lifted() for view in views):
        return [unrefined(view, config) for view, config in zip(views, configs)], [None] * len(views)
    planes = settle(runner, views, configs, spans, chunk)
    return [refined(view, plane, config) for view, plane, config in zip(views, planes, configs)], planes


def refine_config(document: dict, refine: bool | RefineConfig, prepared: dict) -> RefineConfig:
    """The refinement's weights: ``refine`` itself, or the model ``document``'s for the prepared tracks' layout."""
    skeleton = next(iter(prepared.values())).skeleton if prepared else H36M17
    return refine if isinstance(refine, RefineConfig) else RefineConfig.for_model(document, skeleton)


def run_network(runner: ModelRunner, view: CameraTracks, depth: float, chunk: int) -> None:
    """The view's tracks through ``runner``'s network with its camera's z = 0 moved to ``depth`` (where the floor
    is thought to be); from the first run (the camera as given) each track's ``SizeEvidence`` of the ankle plane."""
    camera = view.camera.with_origin_at_height(depth) if depth else view.camera
    view.depth, view.networks = depth, {}
    for track, entry in view.prepared.items():
        try:
            view.networks[track] = runner.network(entry, camera, view.options.flip_test, chunk, view.progress[track])
        except InputError as err:
            view.networks[track] = err
    if not depth:
        view.found = {track: size_evidence(on_observed_rays(joints, camera.center, view.prepared[track].rays),
                                           camera.center, view.prepared[track].feet_seen
                                           & view.prepared[track].observed, view.prepared[track].fps)
                      for track, joints in view.networks.items() if not isinstance(joints, InputError)}


def settle(runner: ModelRunner, views: list[CameraTracks], configs: list[RefineConfig], spans: list[dict] | None,
           chunk: int) -> list[AnklePlane]:
    """Each view's ankle plane on the views' one floor: given (the views' ``floor_z``, which must agree), or
    observed from their people, what each view saw before (``LiftOptions.seen_before``: ``SizeEvidence`` of
    people and ``SeenTwice`` of ankles) and, with ``spans``, the people two cameras saw at once
    (``people_seen_twice``), and decided against the camera files' floor. Each view's keypoints stand on it at
    their own detector's height (``RefineConfig.keypoint_ankle_height_m``), so the evidence is read as the floor's
    (``floor_evidence``), then each view's plane put on it. Where the floor lies off the cameras' z = 0, every
    view's network is run again with the camera's height over it (the network reads the camera's height as given).
    (Reading people's sizes again from that run moved the plane by under 2 mm on ``level-test``: it is read
    once.)"""
    given = {view.options.floor_z for view in views if view.options.floor_z is not None}
    if len(given) > 1:
        raise InputError(f"floor_z: the cameras of one site stand on one floor; got {sorted(given)}", ("floor_z",))
    contact_sd = max(config.keypoint_ankle_sd_m for config in configs)
    if given:
        floor = given_ankle_plane(given.pop(), 0.0, contact_sd)
    else:
        before = [e for view in views for e in view.options.seen_before]
        sizes = [e for e in before if isinstance(e, SizeEvidence)]
        sizes += [e for view in views for e in view.found.values() if e is not None]
        ankles = [e for e in before if isinstance(e, SeenTwice)]
        for (i, first), (j, second) in itertools.combinations(enumerate(views), 2) if spans else ():
            contact = (configs[i].keypoint_ankle_height_m + configs[j].keypoint_ankle_height_m) / 2
            both = [dataclasses.replace(e, height_m=e.height_m - contact)
                    for e in people_seen_twice([(first, spans[i]), (second, spans[j])])]
            first.ankles += both
            second.ankles += both
            ankles += both
        floor = observe_ankle_plane(sizes, 0.0, contact_sd, body.ADULT_BODY_SIZE_M,
                                    max(config.read_size_sd for config in configs), tuple(ankles))
    for view in views:
        if view.depth != floor.height_m:
            run_network(runner, view, floor.height_m, chunk)
    return [floor.standing(config.keypoint_ankle_height_m) for config in configs]


def unrefined(view: CameraTracks, config: RefineConfig) -> dict:
    """A view's tracks as the network put them, with its uncertainty."""
    return {track: joints if isinstance(joints, InputError) else lift_result(
        view.prepared[track], joints, network_position_sd(joints, view.camera, config), None, view.options.smooth_3d)
        for track, joints in view.networks.items()}


def refined(view: CameraTracks, plane: AnklePlane, config: RefineConfig) -> dict:
    """A view's tracks refined on ``plane`` (the network having read the camera's height over the floor found:
    ``settle``), the feet resting there; the output in the camera file's frame. {track: LiftResult, or the
    InputError that stopped it}."""
    depth = view.depth
    camera, floor = view.camera.with_origin_at_height(depth), view.options.floor.lowered(depth)
    config = dataclasses.replace(config, ankle_plane_sd_m=plane.sd_m)
    results = {}
    for track, joints in view.networks.items():
        entry = view.prepared[track]
        try:
            if isinstance(joints, InputError):
                raise joints
            joints, refinement = refine_track(joints, camera, entry.fps, entry.rays, entry.observed, config,
                                              feet_seen=entry.feet_seen, floor=floor)
        except InputError as err:
            results[track] = err
            continue
        joints = joints + [0.0, 0.0, depth]  # back in the camera file's frame
        refinement = dataclasses.replace(refinement, floor_height_m=refinement.floor_height_m + depth)
        results[track] = lift_result(entry, joints, refinement.position_sd_m,
                                     {**refinement.summary(), "ankle_plane": plane.summary()}, view.options.smooth_3d)
    return results


def lift_result(prepared: PreparedTrack, joints: np.ndarray, position_sd: np.ndarray, refinement: dict | None,
                smooth_3d: str | None) -> LiftResult:
    """A track's ``LiftResult``: its joints smoothed as asked, what was missing, its rate, uncertainty and
    refinement."""
    return LiftResult(temporal.smooth(joints, smooth_3d, prepared.fps), prepared.missing, prepared.fps,
                      np.arange(len(joints)), refinement=refinement, position_sd=position_sd)
