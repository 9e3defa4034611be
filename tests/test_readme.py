"""The README's Python quick start, run as written on what ``ray3d video`` writes: a short video of two people
walking (one of them missed by the detector for a few frames), run through ``ray3d video`` with a detector that
reports BlazePose-33, as MediaPipe does, where the people are; then the README's quick-start blocks run in the
folder that holds ``camera.json`` and ``walk-3d/``. Every ``ray3d`` name the README's other Python blocks use
exists."""

from __future__ import annotations

import ast
import importlib
import json
import re
from pathlib import Path

import cv2
import numpy as np
import pytest

from ray3d import Camera
from ray3d.cli import main
from ray3d.data.detector_emulation import detector_points
from ray3d.demo import demo_clip
from ray3d.io.keypoints import read_keypoints
from ray3d.io.world import LiftResult, read_world
from ray3d.lifting.tracks import LiftedTracks
from ray3d.skeleton import BLAZEPOSE33, COCO17
from ray3d.video import DETECTORS, Detection

README = Path(__file__).resolve().parents[1] / "README.md"
QUICK_START_BLOCKS = 2  # the Python section's first blocks: from ray3d video's outputs, then one person's array
SIZE, FPS, FRAMES = (640, 480), 20.0, 40
CAMERA = Camera.from_height_pitch(3.0, 15.0, SIZE, hfov_deg=70.0)
MISSED = range(18, 22)  # frames in which the detector misses the first person
# Each BlazePose-33 point MediaPipe reports from the COCO-17 point nearest it (hands at the wrists, feet at the
# ankles, the inner and outer eyes at the eyes, the mouth at the nose).
NEAREST_COCO = {"eye_inner": "eye", "eye_outer": "eye", "mouth": "nose", "pinky": "wrist", "index": "wrist",
                "thumb": "wrist", "heel": "ankle", "foot_index": "ankle"}


def python_blocks(section: str) -> list[str]:
    """The ```python blocks of the README's ``## section``."""
    text = README.read_text()
    body = text.split(f"\n## {section}\n", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"^```python\n(.*?)^```", body, flags=re.S | re.M)


def _blazepose(world_joints: np.ndarray) -> np.ndarray:
    """(T, 33, 2) the BlazePose-33 pixels of a (T, 17, 3) H36M-17 person seen by ``CAMERA``."""
    coco = CAMERA.project(detector_points(world_joints, COCO17))
    rows = []
    for name in BLAZEPOSE33.joint_names:
        side, _, part = name.partition("_") if name[:2] in ("l_", "r_") else ("", "", name)
        source = f"{side}_{NEAREST_COCO.get(part, part)}" if side else NEAREST_COCO.get(part, part)
        rows.append(COCO17.index(source if source in COCO17.joint_names else "nose"))
    return coco[:, rows]


class BlazePoseStub:
    """Where the people are, in BlazePose-33 as MediaPipe reports them; nobody in the frames it misses."""

    layout, name = BLAZEPOSE33.name, "stub"

    def __init__(self, people_pixels: list[np.ndarray], missed: set):
        self.people, self.missed, self.calls = people_pixels, missed, 0

    def prepare(self, frames) -> None:
        pass

    def __call__(self, frame, time_left_s=None) -> list[Detection]:
        t, self.calls = self.calls, self.calls + 1
        return [Detection(pixels[t].copy(), np.full(len(pixels[t]), 0.9), 0.9)
                for person, pixels in enumerate(self.people) if (person, t) not in self.missed]


def _walker(start_xy, velocity_xy) -> np.ndarray:
    """(T, 17, 3): the bundled clip's pose about its pelvis, carried along a straight line on the floor."""
    clip = demo_clip()[:FRAMES].astype(np.float64)
    clip[..., :2] -= clip[:, :1, :2]
    path = np.asarray(start_xy) + np.outer(np.arange(FRAMES) / FPS, velocity_xy)
    return clip + np.concatenate([path, np.zeros((FRAMES, 1))], axis=-1)[:, None]


@pytest.fixture(scope="module")
def video_outputs(tmp_path_factory) -> Path:
    """A folder as a README reader's: camera.json, walk.mp4 and what ``ray3d video walk.mp4 --camera
    camera.json --out walk-3d/`` wrote there."""
    folder = tmp_path_factory.mktemp("reader")
    (folder / "camera.json").write_text(json.dumps(CAMERA.to_dict()))
    writer = cv2.VideoWriter(str(folder / "walk.mp4"), cv2.VideoWriter_fourcc(*"mp4v"), FPS, SIZE)
    for _ in range(FRAMES):
        writer.write(np.full((SIZE[1], SIZE[0], 3), 60, np.uint8))
    writer.release()
    people = [_blazepose(_walker((6.0, -2.0), (0.0, 1.0))), _blazepose(_walker((9.0, 2.5), (0.0, -1.2)))]
    with pytest.MonkeyPatch.context() as patch:
        patch.setitem(DETECTORS, "stub", lambda camera: BlazePoseStub(people, {(0, t) for t in MISSED}))
        patch.chdir(folder)
        assert main(["video", "walk.mp4", "--camera", "camera.json", "--detector", "stub", "--no-overlay",
                     "--out", "walk-3d/"]) == 0
    return folder


def test_ray3d_video_writes_blazepose_33_with_a_gap_where_the_detector_missed(video_outputs):
    """The input the quick start is run on is what the README says ``ray3d video`` writes."""
    keypoints = read_keypoints(video_outputs / "walk-3d" / "keypoints.json")
    assert keypoints.layout == "blazepose33" and keypoints.fps == pytest.approx(FPS)
    tracks = keypoints.by_track()
    assert len(tracks) == 2
    gaps = [np.setdiff1d(np.arange(t.frames.min(), t.frames.max() + 1), t.frames) for t in tracks.values()]
    assert sorted(len(gap) for gap in gaps) == [0, len(MISSED)]


@pytest.fixture(scope="module")
def quick_start(video_outputs) -> tuple[list[str], dict]:
    """The README's quick-start blocks, and what running them in the reader's folder made."""
    blocks = python_blocks("Python")[:QUICK_START_BLOCKS]
    assert "read_keypoints(" in blocks[0] and ".lift_tracks(" in blocks[0]
    assert ".lift(" in blocks[1] and "frames=" in blocks[1]
    names: dict = {}
    with pytest.MonkeyPatch.context() as patch:
        patch.chdir(video_outputs)
        for block in blocks:
            exec(compile(block, str(README), "exec"), names)  # as a reader pastes them, one after the other
    return blocks, {name: value for name, value in names.items() if not name.startswith("__")}


def test_the_readme_quick_start_runs_as_written_on_ray3d_videos_outputs(video_outputs, quick_start):
    blocks, names = quick_start
    people, result = names["people"], names["result"]
    assert isinstance(people, LiftedTracks) and len(people) == 2 and not people.unliftable
    assert isinstance(result, LiftResult)
    world = read_world(video_outputs / "walk-3d" / "world.json")  # what ray3d video lifted, as the README says
    assert sorted(world.tracks) == sorted(str(track) for track in people)
    for track, lifted in people.items():
        np.testing.assert_array_equal(world.track(track).frames, lifted.frames)
        np.testing.assert_allclose(world.track(track).joints, lifted.joints, rtol=0, atol=1e-4)
    # The second block on every track, the one the detector missed for a few frames among them: lifted over
    # every frame from its first to its last, the missed ones filled in.
    for track, detections in names["tracks"].items():
        run = {**names, "track": track}
        exec(compile(blocks[1], str(README), "exec"), run)
        alone = run["result"]
        np.testing.assert_array_equal(alone.frames, np.arange(detections.frames[0], detections.frames[-1] + 1))
        np.testing.assert_array_equal(alone.frames, people[track].frames)
        skipped = ~np.isin(alone.frames, detections.frames)
        assert alone.interpolated[skipped].all() and alone.refinement["ankle_plane"]["people"] <= 1
    assert sum(len(d.frames) < np.ptp(d.frames) + 1 for d in names["tracks"].values()) == 1


def _resolved(node: ast.expr, names: dict):
    """What a name or dotted name of a README block stands for: looked up in ``names`` (what the quick start
    made, what the blocks import) or in ray3d; ``None`` for anything else (a call's result, a name the reader
    supplies); ``AttributeError`` naming it when it does not exist."""
    parts = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    if not isinstance(node, ast.Name) or (node.id not in names and node.id != "ray3d"):
        return None
    value = names[node.id] if node.id in names else importlib.import_module("ray3d")
    for part in reversed(parts):
        if not hasattr(value, part) and hasattr(value, "__path__"):  # a ray3d submodule not imported yet
            importlib.import_module(f"{value.__name__}.{part}")
        if not hasattr(value, part):
            raise AttributeError(f"{ast.unparse(node)}...{part}: {type(value).__name__} has no {part!r}")
        value = getattr(value, part)
    return value


def _check_names(block: str, names: dict) -> None:
    """Every ray3d name ``block`` imports or uses exists, as do the attributes it reads of what the quick start
    made (``people.ankle_plane``), and every call of a ray3d function or method takes the arguments it is given."""
    import inspect

    tree = ast.parse(block)
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module.split(".")[0] == "ray3d":
            module = importlib.import_module(node.module)
            names.update({alias.asname or alias.name: getattr(module, alias.name) for alias in node.names})
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Load):
            _resolved(node, names)
        function = _resolved(node.func, names) if isinstance(node, ast.Call) else None
        if callable(function) and (getattr(function, "__module__", None) or "").startswith("ray3d"):
            signature = inspect.signature(function)
            signature.bind_partial(*node.args, **{k.arg: k.value for k in node.keywords if k.arg})


def test_every_ray3d_name_of_the_readmes_python_blocks_exists(quick_start):
    """The README's other Python blocks need the reader's files and arrays; what they name of ray3d exists and
    what they call takes the arguments they give it."""
    blocks = re.findall(r"^```python\n(.*?)^```", README.read_text(), flags=re.S | re.M)
    _, names = quick_start
    assert len(blocks) > QUICK_START_BLOCKS
    for block in blocks:
        _check_names(block, dict(names))
    with pytest.raises(AttributeError, match="ankle_plane"):  # the check finds what the issue found
        _check_names("result.ankle_plane", dict(names))
    with pytest.raises(TypeError, match="frame_numbers"):
        _check_names("lifter.lift(pixels, camera, frame_numbers=frames)", dict(names))
