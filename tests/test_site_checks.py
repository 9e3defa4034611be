"""Site files checked (issue 68): a zone whose sides cross (its corners out of order) is refused in one line
naming it; a zone or line drawn in pixels, far from the floor the cameras see or where nobody goes is warned of
("are these metres?") by ``ray3d site``, ``ray3d video --site`` and ``ray3d live --site``, which go on."""

from __future__ import annotations

import json
from pathlib import Path

import cv2
import numpy as np
import pytest

from ray3d import InputError, cameras
from ray3d.cli import main
from ray3d.demo import demo_clip
from ray3d.io.world import LiftResult, World, read_world, write_world
from ray3d.site import CountingLine, Site, Zone
from ray3d.site.checks import FAR_M, NEAR_M, crossing_sides, distance_to, floor_seen, people_places, site_doubts
from ray3d.site.files import read_site

CAMERA = cameras.h36m("S9", "54138969")
PIXELS = {"zones": [{"name": "door", "polygon": [[100, 400], [700, 400], [700, 570], [100, 570]]}],
          "lines": [{"name": "till", "start": [300, 450], "end": [500, 450]}]}
BENCHMARKS = Path(__file__).parent.parent / "benchmarks"


def _write(folder: Path, name: str, document: dict) -> Path:
    path = folder / name
    path.write_text(json.dumps(document))
    return path


def _walker() -> np.ndarray:
    """(T, 17, 3) world joints of the demo clip, walking where the camera looks."""
    return demo_clip()[:60]


def _world(folder: Path) -> Path:
    joints = _walker()
    return write_world(folder / "w.json", World({"7": LiftResult(joints, np.zeros(joints.shape[:2], bool), 30.0,
                                                                 np.arange(len(joints)))}, CAMERA, "test"))


def _around_the_walker(margin: float = 1.0) -> dict:
    """A site whose zone and line lie where the walker walks."""
    places = _walker()[:, 0, :2]
    low, high = places.min(axis=0) - margin, places.max(axis=0) + margin
    middle = (low + high) / 2
    return {"zones": [{"name": "floor", "polygon": [[low[0], low[1]], [high[0], low[1]], [high[0], high[1]],
                                                    [low[0], high[1]]]}],
            "lines": [{"name": "middle", "start": [middle[0], low[1]], "end": [middle[0], high[1]]}]}


@pytest.mark.parametrize("polygon, crosses", [
    ([[0, 0], [1, 0], [1, 1], [0, 1]], False),
    ([[0, 0], [1, 0], [1, 1], [0, 1], [0, 0]], False),          # closed by repeating its first corner
    ([[0, 0], [4, 0], [4, 4], [2, 1], [0, 4]], False),          # concave, simple
    ([[0, 0], [1, 1], [1, 0], [0, 1]], True),                   # a bow tie: two corners swapped
    ([[0, 0], [2, 0], [2, 2], [1, 0], [0, 2]], True),           # a corner touching another side
    ([[0, 0], [3, 0], [3, 1], [1, 1], [1, 0], [2, 0], [2, 2], [0, 2]], True),  # sides overlapping along a line
])
def test_crossing_sides_finds_a_polygon_that_crosses_itself(polygon, crosses):
    found = crossing_sides(np.array(polygon, dtype=float))
    assert (found is not None) == crosses
    if polygon == [[0, 0], [1, 1], [1, 0], [0, 1]]:
        assert found[:2] == (0, 2) and np.allclose(found[2], [0.5, 0.5])


def test_the_benchmark_site_is_simple_and_its_corners_swapped_are_refused_naming_the_zone(tmp_path):
    document = json.loads((BENCHMARKS / "vtest_site.json").read_text())
    assert len(read_site(BENCHMARKS / "vtest_site.json").zones) == 2
    corners = document["zones"][1]["polygon"]
    corners[1], corners[2] = corners[2], corners[1]  # the east junction, its corners in the wrong order
    path = _write(tmp_path, "site.json", document)
    with pytest.raises(InputError) as caught:
        read_site(path)
    message = str(caught.value)
    assert str(path) in message and "zones[1]" in message and "'east junction' crosses itself" in message
    assert "\n" not in message


def test_ray3d_site_refuses_a_self_crossing_zone_in_one_line_and_writes_nothing(tmp_path, capsys):
    world = _world(tmp_path)
    site = _write(tmp_path, "s.json", {"zones": [{"name": "bow tie", "polygon": [[0, 0], [1, 1], [1, 0], [0, 1]]}]})
    capsys.readouterr()
    assert main(["site", str(world), "--site", str(site), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "'bow tie' crosses itself" in err and "s.json" in err, err
    assert not (tmp_path / "out").exists()


def test_a_site_in_pixels_is_doubted_place_by_place_and_one_in_metres_is_not():
    site = Site((Zone("door", np.array(PIXELS["zones"][0]["polygon"], float)),),
                (CountingLine("till", np.array([300.0, 450.0]), np.array([500.0, 450.0])),))
    alone = site_doubts(site)  # no camera, no people: only the size gives it away
    assert [d.place for d in alone] == ["zone 'door'", "line 'till'"]
    assert all(str(d).endswith("are these metres?") and "from the origin" in str(d) for d in alone)
    seen = {d.place: str(d) for d in site_doubts(site, [CAMERA], _walker()[:, 0, :2])}
    assert set(seen) == {"zone 'door'", "line 'till'"}
    door = seen["zone 'door'"]
    assert f"camera {CAMERA.name}" in door and "from the floor" in door and "no person came within" in door
    metres = _around_the_walker()
    good = Site((Zone("floor", np.array(metres["zones"][0]["polygon"], float)),),
                (CountingLine("middle", *np.array([metres["lines"][0]["start"], metres["lines"][0]["end"]], float)),))
    assert site_doubts(good) == [] and site_doubts(good, [CAMERA], _walker()[:, 0, :2]) == []


def test_a_place_the_camera_sees_but_nobody_comes_near_is_doubted_for_that_alone():
    places = _walker()[:, 0, :2]
    seen = floor_seen(CAMERA)
    far_corner = seen[np.argmax(np.linalg.norm(seen - places.mean(axis=0), axis=1))]  # in view, far from the walk
    corner = Zone("corner", far_corner + np.array([[0, 0], [0.5, 0], [0.5, 0.5], [0, 0.5]]))
    assert distance_to(corner, places) > NEAR_M
    [doubt] = site_doubts(Site((corner,)), [CAMERA], places)
    assert doubt.reasons == (doubt.reasons[0],) and doubt.reasons[0].startswith("no person came within")
    assert site_doubts(Site((corner,)), [CAMERA]) == []  # the camera sees it: without people nothing is doubted
    beyond = Zone("beyond", CAMERA.center[:2] + [FAR_M + 10, 0] + corner.polygon - corner.polygon[0])  # too far
    assert "reaches" in str(site_doubts(Site((beyond,)), [CAMERA])[0])


def test_ray3d_site_warns_of_a_site_in_pixels_naming_each_place_and_goes_on(tmp_path, capsys):
    world = _world(tmp_path)
    site = _write(tmp_path, "pixels.json", PIXELS)
    capsys.readouterr()
    assert main(["site", str(world), "--site", str(site), "--out", str(tmp_path / "out")]) == 0
    warnings = [line for line in capsys.readouterr().err.splitlines() if line.startswith("warning:")]
    assert len(warnings) == 2, warnings
    assert "zone 'door'" in warnings[0] and "line 'till'" in warnings[1]
    assert all("pixels.json" in w and w.endswith("are these metres?") for w in warnings)
    good = _write(tmp_path, "metres.json", _around_the_walker())
    assert main(["site", str(world), "--site", str(good), "--out", str(tmp_path / "out2")]) == 0
    assert "warning:" not in capsys.readouterr().err
    assert people_places(read_world(world)).shape == (60, 2)


def _tiny_video(path: Path) -> Path:
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"MJPG"), 10.0, tuple(CAMERA.image_size))
    for _ in range(3):
        writer.write(np.zeros((CAMERA.image_size[1], CAMERA.image_size[0], 3), np.uint8))
    writer.release()
    return path


@pytest.mark.parametrize("command", ["video", "live"])
def test_video_and_live_warn_of_a_site_in_pixels_before_they_start(command, tmp_path, capsys):
    video = _tiny_video(tmp_path / "clip.avi")
    camera = _write(tmp_path, "camera.json", CAMERA.to_dict())
    site = _write(tmp_path, "pixels.json", PIXELS)
    capsys.readouterr()
    extra = ["--no-page", "--until", "1"] if command == "live" else ["--no-overlay"]
    main([command, str(video), "--camera", str(camera), "--site", str(site), "--out", str(tmp_path / "out"), *extra])
    err = capsys.readouterr().err
    warnings = [line for line in err.splitlines() if line.startswith("warning:")]
    assert any("zone 'door'" in w and "are these metres?" in w and f"camera {CAMERA.name}" in w for w in warnings), err
    assert err.index("zone 'door'") < (err.index("error:") if "error:" in err else len(err))
