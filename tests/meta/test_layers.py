"""The import graph of the package, declared: each subpackage (and top-level module) may import only the
ones listed for it. A new dependency is a design decision: add it here, with the reason in DESIGN.md."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[2] / "src" / "alight"

_MODELS = {
    "types",
    "errors",
    "airframe",
    "airframes",
    "cameras",
    "pads",
    "numerics",
    "blockspec",
    "settings",
    "yaml_io",
}
_STAGES = {"perception", "estimation", "planning", "control", "mission", "energy"}

ALLOWED: dict[str, set[str]] = {
    # the messages take their frame helpers (and FloatArray) from the numerics
    "types": {"numerics"},
    "errors": set(),
    # what a block is (the stages' registries' entry type): a leaf below every stage
    "blockspec": set(),
    # the settings dataclasses' pydantic configuration and the scenario sections derived from them
    "settings": set(),
    # the one YAML loader of the configuration files (scenarios, campaigns, airframes, device profiles)
    "yaml_io": {"errors"},
    "airframe": {"types", "errors"},
    # the packaged airframe files and their loader
    "airframes": {"types", "errors", "airframe", "yaml_io"},
    # shared numerics (rotations and angles, Cholesky, polynomial roots, DLT/RANSAC, run labelling): a
    # leaf below every stage and below the messages
    "numerics": {"errors"},
    "cameras": {"types", "errors", "numerics", "blockspec", "yaml_io"},
    "pads": {"types", "errors", "blockspec"},
    # a leaf: the energy and QoS models and policies, no pipeline stage, no simulator
    "energy": {"types", "errors", "yaml_io"},
    "perception": {"types", "errors", "cameras", "pads", "energy", "numerics", "blockspec"},
    "estimation": {"types", "errors", "cameras", "numerics", "blockspec"},
    "planning": {"types", "errors", "airframe", "numerics", "blockspec"},
    "control": {"types", "errors", "airframe", "numerics", "blockspec"},
    "mission": _MODELS | {"perception", "estimation", "planning", "control", "energy"},
    # the fault models take their scenario sections (for annotations only: no runtime import)
    "sim": {"types", "errors", "airframe", "cameras", "pads", "numerics", "scenario", "settings", "yaml_io"},
    # the world of one mission (sim/world.py) and its fused 1 kHz loop (sim/physics.py): the simulator's
    # models, and the autopilot's body-rate loop and mixer (control.rate, control.mixer) that the vehicle
    # runs inside the physics; the flying side's composition only through its VehicleSetup Protocol
    "sim.world": {
        "types",
        "errors",
        "airframe",
        "cameras",
        "pads",
        "numerics",
        "scenario",
        "settings",
        "sim",
        "control",
    },
    # the scenario validates its blocks against the registry (alight.mission.blocks) and its airframe
    "scenario": {"errors", "mission", "airframes", "sim", "settings", "yaml_io"},
    "evaluation": _MODELS | _STAGES | {"sim", "sim.world", "scenario", "__init__"},
    # the bridge compiles the pipeline's kernels (warmup) before it takes the link
    "interfaces": _MODELS | _STAGES | {"sim", "sim.world", "scenario", "evaluation", "compile", "__init__"},
    # numba's cache directory, and compiling the kernels before a worker reports ready: in helper
    # processes from the kernel list, then by flying short missions (evaluation, sim.world: the platform
    # paths; mission: the preset names and blocks); its modules import one way (COMPILE_ORDER)
    "compile": {"errors", "scenario", "mission", "evaluation", "sim.world", "process_stats"},
    "campaign": {
        "types",
        "errors",
        "scenario",
        "mission",
        "evaluation",
        "compile",
        "process_stats",
        "__init__",
    },
    "cli": _MODELS
    | _STAGES
    | {"sim", "sim.world", "scenario", "evaluation", "campaign", "interfaces", "compile", "__init__"},
    # the package's import points numba's cache at a directory keyed by the source, before any kernel
    "__init__": {"compile"},
    # a leaf: this process's resource use
    "process_stats": set(),
}


SUBUNITS = {"sim.world": "sim.world", "sim.physics": "sim.world"}
"""Modules that are a unit of their own inside a subpackage, ``module -> unit``: the rest of the subpackage
may not import them (``sim``'s models know nothing of the world that composes them)."""

COMPILE_ORDER = ("cache", "meter", "parallel", "warmup", "kernel_list")
"""The modules of ``alight.compile``, each importing only those before it: no cycle inside the package."""


def _unit_of_module(dotted: str) -> str:
    """The unit of ``alight.<dotted>`` (``dotted`` without the ``alight.`` prefix)."""
    parts = dotted.split(".")
    return SUBUNITS.get(".".join(parts[:2]), parts[0])


def _unit(path: Path) -> str:
    rel = path.relative_to(SRC)
    if len(rel.parts) == 1:
        return rel.stem
    return _unit_of_module(".".join((*rel.parts[:-1], rel.stem)))


def _imports(path: Path) -> set[str]:
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        names: list[str] = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names = [node.module]
        for n in names:
            if n == "alight":
                out.add("__init__")
            elif n.startswith("alight."):
                out.add(_unit_of_module(n.removeprefix("alight.")))
    return out


def _alight_modules(path: Path) -> set[str]:
    """The ``alight.*`` modules ``path`` imports, dotted, also ``from alight.x import module``'s."""
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            out.update(a.name for a in node.names if a.name.startswith("alight."))
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            if node.module.startswith("alight."):
                out.add(node.module)
                out.update(f"{node.module}.{a.name}" for a in node.names)
    return out


def test_every_subpackage_is_declared() -> None:
    units = {_unit(p) for p in SRC.rglob("*.py")}
    assert units <= set(ALLOWED), sorted(units - set(ALLOWED))


@pytest.mark.parametrize("unit", sorted(ALLOWED))
def test_imports_follow_the_declared_graph(unit: str) -> None:
    files = [p for p in SRC.rglob("*.py") if _unit(p) == unit]
    for path in files:
        bad = _imports(path) - ALLOWED[unit] - {unit}
        assert not bad, (
            f"{path.relative_to(SRC.parent)} imports alight.{sorted(bad)} (allowed: {sorted(ALLOWED[unit])})"
        )


def test_the_graph_has_no_cycle_through_the_pipeline_stages() -> None:
    # the stages and the shared models form a DAG (the scenario <-> mission pair is a late import)
    graph = {u: ALLOWED[u] & (_MODELS | _STAGES) for u in _MODELS | _STAGES}
    seen: dict[str, int] = {}

    def visit(u: str) -> None:
        assert seen.get(u) != 1, f"cycle through {u}"
        if seen.get(u) == 2:
            return
        seen[u] = 1
        for v in graph[u]:
            visit(v)
        seen[u] = 2

    for u in graph:
        visit(u)


def test_the_compile_package_imports_one_way() -> None:
    files = {p.stem for p in (SRC / "compile").glob("*.py")} - {"__init__"}
    assert files == set(COMPILE_ORDER), sorted(files ^ set(COMPILE_ORDER))
    for i, name in enumerate(COMPILE_ORDER):
        imported = {m.split(".")[2] for m in _alight_modules(SRC / "compile" / f"{name}.py")
                    if m.startswith("alight.compile.") and m.split(".")[2] in COMPILE_ORDER}  # fmt: skip
        later = imported - set(COMPILE_ORDER[:i])
        assert not later, f"alight.compile.{name} imports alight.compile.{sorted(later)}, not above it"
    init = _alight_modules(SRC / "compile" / "__init__.py")
    assert not init, f"alight/compile/__init__.py imports {sorted(init)}: alight imports it first of all"
