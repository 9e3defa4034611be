"""The house: which rooms may import which (read from the source, every import, lazy ones included), no
import cycles, no oversized modules, and training configs that list only what they change."""

from __future__ import annotations

import ast
import dataclasses
import json
from pathlib import Path

import pytest

import ray3d
from ray3d.models.presets import PRESETS
from ray3d.train import TrainConfig, config_document

PACKAGE = Path(ray3d.__file__).parent
REPOSITORY = PACKAGE.parents[1]
MAX_LINES = 400


def _module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


MODULES = {_module_name(p): p for p in PACKAGE.rglob("*.py")}


def _imports(module: str) -> set[str]:
    """The ray3d modules ``module`` imports (a name imported from a package counts as the submodule when
    there is one of that name, else as the package)."""
    found = set()
    for node in ast.walk(ast.parse(MODULES[module].read_text())):
        if isinstance(node, ast.Import):
            found |= {alias.name for alias in node.names if alias.name.startswith("ray3d")}
        elif isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("ray3d"):
            for alias in node.names:
                candidate = f"{node.module}.{alias.name}"
                found.add(candidate if candidate in MODULES else node.module)
    return {name for name in found if name in MODULES and name != module}


GRAPH = {module: _imports(module) for module in MODULES}


def _in_room(module: str, room: str) -> bool:
    return module == room or module.startswith(room + ".")


@pytest.mark.parametrize("importer, forbidden", [
    ("ray3d.models", "ray3d.data"), ("ray3d.lifting", "ray3d.data"), ("ray3d.geometry", "ray3d.data"),
    ("ray3d.temporal", "ray3d.data"), ("ray3d.io", "ray3d.lifting"), ("ray3d.io", "ray3d.data"),
    ("ray3d.io", "ray3d.models"), ("ray3d.video", "ray3d.data"), ("ray3d.geometry", "ray3d.models"),
    ("ray3d.batch", "ray3d.data"), ("ray3d.lifting", "ray3d.batch"), ("ray3d.video", "ray3d.batch"),
    ("ray3d.site.places", "ray3d.io"), ("ray3d.io", "ray3d.site.events"), ("ray3d.io", "ray3d.site.report"),
    ("ray3d.io", "ray3d.site.analytics"), ("ray3d.site", "ray3d.live"), ("ray3d.site", "ray3d.jobs"),
    ("ray3d.live", "ray3d.jobs"), ("ray3d.fusion", "ray3d.jobs"), ("ray3d.video", "ray3d.jobs"),
    ("ray3d.lifting", "ray3d.jobs"), ("ray3d.jobs", "ray3d.cli"), ("ray3d.viz", "ray3d.jobs"),
])
def test_rooms_do_not_import_what_stands_on_them(importer, forbidden):
    offenders = sorted(f"{m} -> {i}" for m, imports in GRAPH.items() if _in_room(m, importer)
                       for i in imports if _in_room(i, forbidden))
    assert not offenders


def test_nothing_imports_the_command_line():
    assert not [m for m, imports in GRAPH.items() if not _in_room(m, "ray3d.cli")
                for i in imports if _in_room(i, "ray3d.cli")]


def test_only_the_command_line_imports_the_public_api():
    """Below the CLI no module imports ``ray3d`` itself, which would drag every room in."""
    assert not [m for m, imports in GRAPH.items() if "ray3d" in imports and not _in_room(m, "ray3d.cli")
                and m != "ray3d"]


def _first_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """A cycle of ``graph`` ({node: the nodes it imports}) as the path round it, or None."""
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for child in sorted(graph.get(node, ())):
            if state.get(child) == 1:
                return stack[stack.index(child):] + [child]
            if child not in state and (cycle := visit(child)):
                return cycle
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state and (cycle := visit(node)):
            return cycle
    return None


def test_there_are_no_import_cycles():
    cycle = _first_cycle({module: imported - {"ray3d"} for module, imported in GRAPH.items()})
    assert cycle is None, " -> ".join(cycle)


def test_no_module_is_over_the_size_limit():
    sizes = {m: len(p.read_text().splitlines()) for m, p in MODULES.items()}
    assert not {m: n for m, n in sizes.items() if n > MAX_LINES}


CONFIGS = sorted((REPOSITORY / "configs").glob("*.json"))


def _changes_only(reference, value) -> bool:
    """Whether ``value`` differs from ``reference`` in every field it gives (nested dicts field by field)."""
    if isinstance(value, dict) and isinstance(reference, dict):
        return all(_changes_only(reference.get(k), v) for k, v in value.items())
    return reference != value


@pytest.mark.skipif(not CONFIGS, reason="no configs/ folder beside the installed package")
@pytest.mark.parametrize("path", [p for p in CONFIGS if "base" in json.loads(p.read_text())], ids=lambda p: p.name)
def test_configs_on_a_base_list_only_what_they_change_from_it(path):
    document = json.loads(path.read_text())
    base = config_document(path.parent / document.pop("base"))
    assert all(_changes_only(base.get(key), value) for key, value in document.items())
    assert TrainConfig.from_json(path).model.name == document.get("model", {}).get("name", base["model"]["name"])


@pytest.mark.skipif(not CONFIGS, reason="no configs/ folder beside the installed package")
@pytest.mark.parametrize("path", [p for p in CONFIGS if "base" not in json.loads(p.read_text())],
                         ids=lambda p: p.name)
def test_configs_name_a_preset_and_list_only_what_they_change(path):
    document = json.loads(path.read_text())
    assert document["preset"] in PRESETS
    base = json.loads(json.dumps(dataclasses.asdict(PRESETS[document["preset"]])))
    assert all(base[k] != v for k, v in document.get("model", {}).items())
    defaults = TrainConfig().to_dict()
    for key, value in document.items():
        if key not in ("preset", "model", "samples"):
            assert defaults[key] != value, key
    for key, value in document.get("samples", {}).items():
        reference = defaults["samples"][key]
        changed = {k: v for k, v in value.items() if reference[k] != v} if key == "cameras" else value
        assert changed == value and reference != value, key
    config = TrainConfig.from_json(path)
    assert config.model.name == document.get("model", {}).get("name", PRESETS[document["preset"]].name)


def _literals(path: Path) -> list[tuple[float, int]]:
    """Every number written in a module's code, with its line."""
    return [(node.value, node.lineno) for node in ast.walk(ast.parse(path.read_text()))
            if isinstance(node, ast.Constant) and isinstance(node.value, float)]


def test_body_measures_are_written_only_in_body():
    """A second copy of a body constant (a stature, an axis height, the head-over-ankle ratio, the size prior)
    diverges from the first: only ``ray3d.body`` may write them."""
    from ray3d import body

    measures = {body.ADULT_STATURE_M, body.ADULT_STATURE_SD_M, body.HEAD_OVER_ANKLE_OF_STATURE,
                body.ADULT_BODY_SIZE_M, body.PLANTED_ANKLE_HEIGHT_M, *body.AXIS_HEIGHTS.values()}
    copies = [f"{module}:{line} {value}" for module, path in MODULES.items() if module != "ray3d.body"
              for value, line in _literals(path) if any(abs(value - m) < 1e-9 for m in measures)]
    assert not copies


def _calls_in(tree: ast.AST, name: str) -> list[int]:
    return [node.lineno for node in ast.walk(tree)
            if isinstance(node, ast.Call) and getattr(node.func, "attr", getattr(node.func, "id", None)) == name]


def _calls(path: Path, name: str) -> list[int]:
    return _calls_in(ast.parse(path.read_text()), name)


def test_a_camera_from_options_is_built_in_one_place():
    """Every job (``lift``, ``video``, batch manifests, later commands) builds its camera through
    ``io.camera_files.camera_from_options``: a second builder from height and pitch is refused."""
    builders = {module: lines for module, path in MODULES.items() if (lines := _calls(path, "from_height_pitch"))}
    assert builders == {"ray3d.io.camera_files": builders.get("ray3d.io.camera_files")} and builders


def test_the_video_header_is_read_once_per_run():
    """Below the entry points (the command line, batch tasks, benchmarks: they read a video's header once and
    pass its ``VideoInfo`` down) only ``video.pipeline.video_info`` reads it, for a caller that gave a path."""
    below = {module: path for module, path in MODULES.items() if _in_room(module, "ray3d.video")
             or _in_room(module, "ray3d.lifting") or _in_room(module, "ray3d.io")}
    readers = {module for module, path in below.items() if _calls(path, "read_video_info")}
    assert readers == {"ray3d.video.pipeline"}
    functions = [node for node in ast.walk(ast.parse(MODULES["ray3d.video.pipeline"].read_text()))
                 if isinstance(node, ast.FunctionDef) and _calls_in(node, "read_video_info")]
    assert [f.name for f in functions] == ["video_info"]


def test_the_readme_code_map_names_every_room_of_the_tree():
    readme = (REPOSITORY / "README.md").read_text()
    section = readme[readme.index("## The code: a map"):readme.index("## Conventions")]
    rooms = {p.name + "/" if p.is_dir() else p.name for p in PACKAGE.iterdir()
             if not p.name.startswith("__") and (p.is_dir() or p.suffix == ".py")}
    assert not {room for room in rooms if f"`{room}`" not in section}


def test_the_top_level_holds_few_loose_modules():
    """Wings are packages (``lifting/``, ``refine/``, ``video/``, ...): the top level keeps at most twelve loose
    modules, so a new concept finds its wing instead of a thirteenth."""
    loose = [p.name for p in PACKAGE.glob("*.py") if p.name != "__init__.py"]
    assert len(loose) <= 12, sorted(loose)


def _callers(name: str) -> set[str]:
    return {module for module, path in MODULES.items() if _calls(path, name)}


@pytest.mark.parametrize("assembler, own_room", [("make_detector", "ray3d.video"), ("camera_for_video", "ray3d.video"),
                                                 ("lift_video", "ray3d.video"), ("lift_file", "ray3d.lifting"),
                                                 ("fuse_worlds", "ray3d.fusion"), ("follow", "ray3d.live"),
                                                 ("LocalCameras", "ray3d.live")])
def test_only_the_jobs_wing_assembles_a_job_or_fuses_worlds(assembler, own_room):
    """A video job (its camera, detector and lifter), a keypoint job, a live job and the fusion of worlds are put
    together in ``ray3d.jobs`` only: a second assembler is refused."""
    assert {m for m in _callers(assembler) if not _in_room(m, own_room)} <= {"ray3d.jobs.run", "ray3d.jobs.live"}


def test_a_site_report_is_made_in_one_place_and_models_are_loaded_by_jobs_and_lifting_only():
    """Every report on a site (``ray3d video --site``, ``ray3d site``, batch rows, live runs) is made by
    ``jobs.run.site_report``; a model is loaded (``Lifter.load``) only in ``jobs`` (a job's, cached per layout)
    and ``lifting``: no front end, pipeline or live camera falls back to a model of its own."""
    assert {m for m in _callers("analyse_site") if not _in_room(m, "ray3d.site")} == {"ray3d.jobs.run"}
    loaders = {module for module, path in MODULES.items() for node in ast.walk(ast.parse(path.read_text()))
               if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "load"
               and isinstance(node.func.value, ast.Name) and node.func.value.id == "Lifter"}
    assert loaders and all(_in_room(m, "ray3d.jobs") or _in_room(m, "ray3d.lifting") for m in loaders), loaders


def test_a_video_or_stream_camera_and_detector_are_put_together_in_one_function():
    functions = {(module, node.name) for module, path in MODULES.items() if _in_room(module, "ray3d.jobs")
                 for node in ast.walk(ast.parse(path.read_text())) if isinstance(node, ast.FunctionDef)
                 and (_calls_in(node, "make_detector") or _calls_in(node, "camera_for_video"))}
    assert functions == {("ray3d.jobs.run", "camera_and_detector")}


def test_one_event_engine_spells_every_event_name():
    """The site's events come from one engine (``site.events``): no other module spells an event's name, finds a
    line crossing or a fall for an event, or defines a second monitor."""
    from ray3d.site.events import EVENT_KINDS

    spellers = {module for module, path in MODULES.items()
                if any(isinstance(node, ast.Constant) and node.value in EVENT_KINDS
                       for node in ast.walk(ast.parse(path.read_text())))}
    assert spellers == {"ray3d.site.events"}
    assert _callers("line_crossings") == _callers("falls") == {"ray3d.site.events"}
    monitors = {module for module, path in MODULES.items() for node in ast.walk(ast.parse(path.read_text()))
                if isinstance(node, ast.ClassDef) and {"update", "ended"} <= {
                    f.name for f in node.body if isinstance(f, ast.FunctionDef)} and "Event" in path.read_text()}
    assert monitors == {"ray3d.site.events"}


def test_every_record_of_where_a_person_stands_is_the_one_positioned_record():
    """A class holding joints with the root's position sd is a ``geometry.uncertainty.Positioned`` (one record,
    one way to turn it into covariances), and no module but that one writes the ray-shaped covariance."""
    records = {(module, node.name, tuple(getattr(base, "id", getattr(base, "attr", "")) for base in node.bases))
               for module, path in MODULES.items() for node in ast.walk(ast.parse(path.read_text()))
               if isinstance(node, ast.ClassDef) and {"joints", "position_sd"} <= {
                   getattr(item.target, "id", None) for item in node.body if isinstance(item, ast.AnnAssign)}}
    assert {(m, name) for m, name, bases in records if "Positioned" not in bases} == \
        {("ray3d.geometry.uncertainty", "Positioned")}
    assert len(records) >= 4
    assert {m for m in MODULES if m != "ray3d.geometry.uncertainty" and _calls(MODULES[m], "along_ray")} == set()


def _room(module: str) -> str:
    """A module's room: its folder under ``ray3d`` (``site`` for ``ray3d.site.events``), or the module itself."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else parts[0]


def test_no_two_rooms_import_each_other():
    """Folder-level cycles, counting every import (those inside functions too): a room that imports another
    which imports it back is one room in two places."""
    rooms: dict[str, set[str]] = {}
    for module, imported in GRAPH.items():
        rooms.setdefault(_room(module), set()).update(_room(m) for m in imported if m != "ray3d")
    for room in rooms:
        rooms[room].discard(room)
    cycle = _first_cycle(rooms)
    assert cycle is None, " -> ".join(cycle)
