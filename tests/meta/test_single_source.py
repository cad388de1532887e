"""One declaration per setting (issue 35): every scenario key has a single source, the field that declares
its type, default, bound and meaning, and something at run time reads it.

A scenario section that feeds a runtime settings dataclass (``RUNTIME_PATH``) is either that dataclass or
a model derived from its fields (``alight.settings.section_model``); a key declared by hand both in the
section and in the dataclass, a preset value that repeats the default, or a hand-written list of a
section's keys in the runtime code (the "these are positive" and "these may be None" tuples) is a second
declaration, and fails here. ``python -m pytest tests/meta/test_single_source.py -s`` prints the table.
"""

from __future__ import annotations

import ast
import dataclasses
import inspect
from collections.abc import Iterator
from functools import cache
from pathlib import Path
from typing import Any

import pytest
import yaml

from alight.mission.guidance import GuidanceConfig
from alight.mission.state_machine import MissionConfig
from alight.mission.touchdown_detector import TouchdownConfig
from alight.scenario import Scenario
from alight.settings import is_section, section_fields, sources
from alight.sim.sensors import OpticalFlowConfig, RangeFinderConfig
from alight.sim.telemetry import TelemetryConfig
from alight.sim.textures import DistractorSpec

SRC = Path(__file__).resolve().parents[2] / "src" / "alight"

RUNTIME_PATH: dict[str, tuple[type, ...]] = {
    "platform.telemetry": (TelemetryConfig,),
    "camera.distractors": (DistractorSpec,),
    "mission": (MissionConfig, GuidanceConfig),
    "mission.touchdown": (TouchdownConfig,),
    "rangefinder": (RangeFinderConfig,),
    "optical_flow": (OpticalFlowConfig,),
}
"""Scenario sections and the runtime settings dataclasses they configure."""


@dataclasses.dataclass(frozen=True)
class Key:
    key: str
    """Dotted scenario key."""
    section: str
    """Dotted key of its section ('' at the top level)."""
    owner: type
    """The class whose field declares it: a settings dataclass, or the hand-written scenario model."""
    field: str
    """That field's name."""

    @property
    def source(self) -> str:
        return f"{self.owner.__module__}.{self.owner.__qualname__}.{self.field}"


def _walk(cls: type, section: str = "") -> Iterator[Key]:
    derived = sources(cls)
    for name, info in section_fields(cls).items():
        key = f"{section}.{name}" if section else name
        sub = is_section(info.annotation)
        if sub is not None:
            yield from _walk(sub, key)
            continue
        owner, field = derived.get(name, (cls, name))
        yield Key(key, section, owner, field)


@cache
def scenario_keys() -> tuple[Key, ...]:
    return tuple(_walk(Scenario))


@cache
def _class_defaults(path: Path) -> dict[str, dict[str, ast.expr]]:
    """Class name -> {field: default expression} of the classes written in ``path``."""
    out: dict[str, dict[str, ast.expr]] = {}
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.ClassDef):
            out[node.name] = {
                s.target.id: s.value
                for s in node.body
                if isinstance(s, ast.AnnAssign) and isinstance(s.target, ast.Name) and s.value is not None
            }
    return out


def _written_defaults(cls: type) -> dict[str, ast.expr]:
    """The fields ``cls``'s own source gives a default (none for a model made by ``section_model``)."""
    return _class_defaults(Path(inspect.getfile(cls))).get(cls.__name__, {})


def _section_class(section: str) -> type:
    cls: type = Scenario
    for part in section.split("."):
        sub = is_section(section_fields(cls)[part].annotation)
        assert sub is not None, section
        cls = sub
    return cls


def test_the_table_of_single_sources() -> None:
    keys = scenario_keys()
    width = max(len(k.key) for k in keys)
    print()
    for k in keys:
        print(f"{k.key:<{width}}  {k.source}")
    by_key = {k.key: k.source for k in keys}
    assert len(by_key) == len(keys) > 150
    assert by_key["mission.land_speed_mps"] == "alight.mission.state_machine.MissionConfig.land_speed_mps"
    assert by_key["mission.intercept"] == "alight.mission.guidance.GuidanceConfig.intercept"
    assert (
        by_key["mission.touchdown.level_to"] == "alight.mission.touchdown_detector.TouchdownConfig.level_to"
    )
    assert by_key["platform.telemetry.rate_hz"] == "alight.sim.telemetry.TelemetryConfig.rate_hz"
    assert by_key["rangefinder.noise_m"] == "alight.sim.sensors.RangeFinderConfig.noise_std_m"
    assert by_key["camera.distractors.count"] == "alight.sim.textures.DistractorSpec.count"


@pytest.mark.parametrize("section", sorted(RUNTIME_PATH))
def test_no_key_is_declared_twice_on_its_way_to_the_runtime(section: str) -> None:
    # declarations of a key: a field with a default written in a runtime dataclass the section feeds, and
    # the section's own field when the section is a scenario model rather than that dataclass
    scenario_side = _section_class(section)
    runtime = RUNTIME_PATH[section]
    keys = [k for k in scenario_keys() if k.section == section]
    assert keys, section
    for k in keys:
        names = {k.field, k.key.rsplit(".", 1)[1]}
        where = [c.__qualname__ for c in runtime for n in sorted(names) if n in _written_defaults(c)]
        if k.owner is scenario_side and scenario_side not in runtime:
            where.append(scenario_side.__qualname__)
        assert len(where) == 1, f"{k.key} is declared {len(where)} times: {where}"


def _preset_files() -> list[Path]:
    return sorted((SRC / "mission" / "preset_data").glob("*.yaml"))


def _runtime_default(classes: tuple[type, ...], name: str) -> Any:
    for c in classes:
        for f in dataclasses.fields(c):
            if f.name == name:
                return f.default_factory() if f.default_factory is not dataclasses.MISSING else f.default
    return dataclasses.MISSING


@pytest.mark.parametrize("path", _preset_files(), ids=lambda p: p.stem)
def test_a_preset_sets_only_values_that_differ_from_the_default(path: Path) -> None:
    # a preset's value equal to the runtime default is a second declaration of that default
    data = yaml.safe_load(path.read_text(encoding="utf-8")).get("mission") or {}
    repeated = []
    for name, value in data.items():
        if name == "touchdown":
            repeated += [
                f"touchdown.{k}" for k, v in value.items() if v == _runtime_default((TouchdownConfig,), k)
            ]
        elif value == _runtime_default(RUNTIME_PATH["mission"], name):
            repeated.append(name)
    assert not repeated, f"{path.name} repeats the default of mission.{repeated}"


def _runtime_files() -> list[Path]:
    return sorted(p for p in SRC.rglob("*.py") if p.name != "scenario.py")


def test_no_hand_written_list_of_a_sections_keys() -> None:
    # "these keys may be None", "these must be positive": a bound or an optional-ness belongs on the field
    names = {
        section: {f.name for c in classes for f in dataclasses.fields(c)}
        for section, classes in RUNTIME_PATH.items()
    }
    found = []
    for path in _runtime_files():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if not isinstance(node, ast.Tuple | ast.List | ast.Set):
                continue
            strings = [e.value for e in node.elts if isinstance(e, ast.Constant) and isinstance(e.value, str)]
            if len(strings) < 3 or len(strings) != len(node.elts):
                continue
            for section, known in names.items():
                if set(strings) <= known:
                    found.append(
                        f"{path.relative_to(SRC)}:{node.lineno} lists {section} keys {strings[:3]}..."
                    )
    assert not found, "\n".join(found)


@cache
def _attributes_read() -> frozenset[str]:
    out: set[str] = set()
    for path in _runtime_files():
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Attribute):
                out.add(node.attr)
            elif isinstance(node, ast.Constant) and isinstance(node.value, str):
                out.add(node.value)  # getattr(x, "name"), a key passed on by name
    return frozenset(out)


def test_every_scenario_key_has_a_runtime_consumer() -> None:
    read = _attributes_read()
    unread = [k.key for k in scenario_keys() if k.field not in read]
    assert not unread, f"scenario keys nothing reads outside scenario.py: {unread}"
