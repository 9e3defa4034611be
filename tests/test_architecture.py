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
from ray3d.train import TrainConfig

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
    ("ray3d.models", "ray3d.data"), ("ray3d.lift", "ray3d.data"), ("ray3d.geometry", "ray3d.data"),
    ("ray3d.temporal", "ray3d.data"), ("ray3d.io", "ray3d.lift"), ("ray3d.io", "ray3d.data"),
    ("ray3d.io", "ray3d.models"), ("ray3d.video", "ray3d.data"), ("ray3d.geometry", "ray3d.models"),
    ("ray3d.batch", "ray3d.data"), ("ray3d.lift", "ray3d.batch"), ("ray3d.video", "ray3d.batch"),
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


def test_there_are_no_import_cycles():
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(module: str) -> list[str] | None:
        state[module] = 1
        stack.append(module)
        for child in sorted(GRAPH[module] - {"ray3d"}):
            if state.get(child) == 1:
                return stack[stack.index(child):] + [child]
            if child not in state and (cycle := visit(child)):
                return cycle
        stack.pop()
        state[module] = 2
        return None

    for module in sorted(GRAPH):
        if module not in state:
            assert (cycle := visit(module)) is None, " -> ".join(cycle)


def test_no_module_is_over_the_size_limit():
    sizes = {m: len(p.read_text().splitlines()) for m, p in MODULES.items()}
    assert not {m: n for m, n in sizes.items() if n > MAX_LINES}


CONFIGS = sorted((REPOSITORY / "configs").glob("*.json"))


@pytest.mark.skipif(not CONFIGS, reason="no configs/ folder beside the installed package")
@pytest.mark.parametrize("path", CONFIGS, ids=lambda p: p.name)
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
