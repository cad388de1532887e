"""Blocks by name: the registry a scenario's ``blocks:`` section and the presets choose from.

Seven stages, each a name from its stage's table (:class:`alight.blockspec.BlockSpec` entries):

    camera              alight.cameras.CAMERAS
    pad                 alight.pads.PADS
    detector            alight.perception.DETECTORS
    geolocator          alight.perception.GEOLOCATORS
    platform_estimator  alight.estimation.PLATFORM_ESTIMATORS
    controller          alight.control.CONTROLLERS
    planner             alight.planning.PLANNERS

:data:`BLOCKS` is those tables by stage (the same dicts, not copies): the flight
(:func:`alight.mission.presets.build_preset` calls each chosen spec's ``build``), ``alight blocks``,
``alight detect``, the docs generator and the contract tests read them, and :func:`register_block` adds a
block from outside the package. Each spec declares its parameters, the values it takes from the scenario,
what it needs of the other stages' choices and what it provides (``needs`` maps ``"<stage>"`` to the
block names it works with, or ``"<stage>.<feature>"`` to the values of that feature in the chosen block's
``provides``). One function, :func:`check_compatibility`, reads them; nothing else decides what goes with
what.

A preset (``mission/preset_data/<name>.yaml``) is a named set of choices with parameters; a scenario's
``blocks:`` entries override its preset's. :func:`resolve_blocks` gives the effective choices (preset +
the scenario's per-block sections + ``blocks:``) and refuses, with a ``ValueError`` whose message names
the scenario key, an unknown name, an unknown or rejected parameter, or an incompatible pair.
This module builds configs only; the objects that fly are made in :mod:`alight.mission.presets`.
"""

from __future__ import annotations

import dataclasses
import enum
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cache
from importlib import resources
from typing import Any

from alight.blockspec import BlockSpec, ResolveContext
from alight.cameras import CAMERAS, CameraLoad, CameraModel, MountedCamera
from alight.cameras.pinhole import CameraMount
from alight.control import CONTROLLERS
from alight.estimation import PLATFORM_ESTIMATORS
from alight.pads import PADS
from alight.perception import DETECTORS, GEOLOCATORS
from alight.planning import PLANNERS
from alight.yaml_io import load_yaml_text

STAGES = ("camera", "pad", "detector", "geolocator", "platform_estimator", "controller", "planner")
"""The stages a ``blocks:`` section names, in data-flow order."""

BLOCKS: dict[str, dict[str, BlockSpec[Any, Any]]] = {
    "camera": CAMERAS,
    "pad": PADS,
    "detector": DETECTORS,
    "geolocator": GEOLOCATORS,
    "platform_estimator": PLATFORM_ESTIMATORS,
    "controller": CONTROLLERS,
    "planner": PLANNERS,
}
"""Every block by stage and name: each stage's own table."""


def register_block(spec: BlockSpec[Any, Any]) -> None:
    """Add ``spec`` to its stage's table, so a scenario's ``blocks.<stage>: <name>`` flies it. Raises
    ``ValueError`` (one line) for an unknown stage or a name the stage has already."""
    table = BLOCKS.get(spec.stage)
    if table is None:
        raise ValueError(f"register_block: unknown stage '{spec.stage}', expected one of {list(STAGES)}")
    if spec.name in table:
        raise ValueError(f"register_block: {spec.stage} '{spec.name}' is registered already")
    table[spec.name] = spec


def unregister_block(stage: str, name: str) -> None:
    """Remove a block :func:`register_block` added (a test's clean-up); unknown ones are ignored."""
    BLOCKS.get(stage, {}).pop(name, None)


def block_spec(stage: str, name: str, where: str | None = None) -> BlockSpec[Any, Any]:
    """The spec of ``name`` in ``stage``'s table; an unknown one is refused with a ``ValueError`` of one
    line naming ``where`` (default ``blocks.<stage>``) and the known names."""
    table = BLOCKS[stage]
    if name not in table:
        raise ValueError(
            f"{where or f'blocks.{stage}'}: unknown {stage} '{name}', expected one of {list(table)}"
        )
    return table[name]


# Scenario sections whose keys are parameters of one stage's block (the sections predate ``blocks:``;
# they stay as its shorthand). ``controller.l1_adaptive`` picks the controller instead (below).
SECTION_STAGE = {"planner": "planner", "estimator": "platform_estimator", "controller": "controller"}


# -- presets as data -------------------------------------------------------------------------------------


@cache
def preset_names() -> tuple[str, ...]:
    files = resources.files("alight.mission").joinpath("preset_data")
    return tuple(sorted(p.name[:-5] for p in files.iterdir() if p.name.endswith(".yaml")))


@cache
def preset_data(name: str) -> Mapping[str, Any]:
    """The preset's YAML (``mission/preset_data/<name>.yaml``): ``description``, ``blocks`` and the
    preset's ``mission`` defaults."""
    if name not in preset_names():
        raise ValueError(f"preset: unknown preset '{name}', expected one of {list(preset_names())}")
    text = resources.files("alight.mission").joinpath("preset_data", f"{name}.yaml").read_text("utf-8")
    data = load_yaml_text(text, f"preset {name}", "preset")
    return data  # type: ignore[no-any-return]


# -- resolution ------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Block:
    """One effective choice: the block and its parameters (all of them, defaults applied)."""

    stage: str
    name: str
    params: Any
    """An instance of the block's ``params`` dataclass."""
    given: Mapping[str, Any]
    """The parameters set by the preset or the scenario (the rest are defaults or context)."""
    spec: BlockSpec[Any, Any] = field(repr=False, compare=False)
    """The block as its stage's table declares it."""

    def as_dict(self) -> dict[str, Any]:
        hidden = set(self.spec.hidden)
        return {
            "name": self.name,
            **{
                f.name: _plain(getattr(self.params, f.name))
                for f in dataclasses.fields(self.params)
                if f.init and f.name not in hidden
            },
        }


def _plain(v: Any) -> Any:
    if dataclasses.is_dataclass(v) and not isinstance(v, type):
        return {f.name: _plain(getattr(v, f.name)) for f in dataclasses.fields(v)}
    if isinstance(v, tuple | list):
        return [_plain(x) for x in v]
    if isinstance(v, enum.Enum) and isinstance(v.value, str | int):
        return v.value
    return v


def parse_entry(entry: Any, where: str) -> tuple[str | None, dict[str, Any]]:
    """A ``blocks:`` entry: a name, or ``{name: ..., <parameters>}`` (``name`` may be left out to set
    the preset's block's parameters)."""
    if isinstance(entry, str):
        return entry, {}
    if isinstance(entry, Mapping):
        params = dict(entry)
        name = params.pop("name", None)
        if name is not None and not isinstance(name, str):
            raise ValueError(f"{where}.name: a block name must be a string, got {name!r}")
        return name, params
    raise ValueError(f"{where}: expected a block name or {{name: ..., <parameters>}}, got {entry!r}")


@dataclass(frozen=True)
class EffectiveBlocks:
    """The blocks a scenario flies, after its preset and its overrides."""

    preset: str
    blocks: Mapping[str, Block]
    mission: Mapping[str, Any]
    """The preset's mission defaults (``land_speed_mps``, ``coverage_fov_deg``)."""
    camera_model: CameraModel | None = None
    """The loaded camera model (vision blocks), or None."""
    color: bool = False
    """Render colour images (a detector that needs colour, or the scenario's ``camera.color``)."""

    def __getitem__(self, stage: str) -> Block:
        return self.blocks[stage]

    def as_dict(self) -> dict[str, Any]:
        return {stage: self.blocks[stage].as_dict() for stage in STAGES}


@dataclass
class _Choices:
    """The names and given parameters of a scenario's blocks, with the key each name comes from."""

    names: dict[str, str]
    preset_names: dict[str, str]
    preset_given: dict[str, dict[str, Any]]
    source: dict[str, str]
    section_params: dict[str, dict[str, Any]] = field(default_factory=dict)
    """Stage -> ``{"<section>.<key>": value}`` from the scenario's per-block sections."""
    blocks_given: dict[str, dict[str, Any]] = field(default_factory=dict)
    """Stage -> the parameters of the scenario's ``blocks.<stage>`` entry."""


def _preset_choices(preset_name: str, preset: Mapping[str, Any]) -> _Choices:
    pblocks = preset.get("blocks", {})
    names: dict[str, str] = {}
    given: dict[str, dict[str, Any]] = {}
    for stage in STAGES:
        name, params = parse_entry(pblocks[stage], f"preset {preset_name}: blocks.{stage}")
        if name is None:
            raise ValueError(f"preset {preset_name}: blocks.{stage}: no block name")
        names[stage], given[stage] = name, params
    source = {stage: f"blocks.{stage} (preset {preset_name})" for stage in STAGES}
    return _Choices(names, dict(names), given, source)


def _scenario_choices(scenario: Any, ch: _Choices) -> None:
    """The scenario's per-block sections (parameters of the stage's block, whichever block that is) and
    its ``blocks:`` entries, over the preset's choices."""
    for section, stage in SECTION_STAGE.items():
        values = {k: v for k, v in getattr(scenario, section).model_dump().items() if v is not None}
        if section == "controller" and "l1_adaptive" in values:
            ch.names["controller"] = "faessler_l1" if values.pop("l1_adaptive") else "faessler"
        ch.section_params[stage] = {f"{section}.{k}": v for k, v in values.items()}
    for stage in STAGES:
        entry = getattr(scenario.blocks, stage)
        ch.blocks_given[stage] = {}
        if entry is None:
            continue
        name, params = parse_entry(entry, f"blocks.{stage}")
        if name is not None:
            ch.names[stage] = name
        ch.blocks_given[stage] = params
        ch.source[stage] = f"blocks.{stage}"


def _given_params(stage: str, spec: BlockSpec[Any, Any], ch: _Choices) -> tuple[dict[str, Any], str]:
    """The parameters the preset and the scenario set for ``stage``'s block, and the key to name in an
    error about them."""
    name = spec.name
    # the preset's parameters belong to the preset's block: another block starts from its defaults
    params = dict(ch.preset_given[stage]) if name == ch.preset_names[stage] else {}
    known = {p for p, _, _ in spec.parameters()}
    for dotted, value in ch.section_params.get(stage, {}).items():
        key = dotted.split(".", 1)[1]
        if key not in known:
            raise ValueError(
                f"{dotted}: not a parameter of {stage} '{name}' ({ch.source[stage]}); "
                f"its parameters: {', '.join(sorted(known))}"
            )
        params[key] = value
    params.update(ch.blocks_given[stage])
    where = ch.source[stage].split(" (preset")[0]
    if ch.section_params.get(stage) and not ch.blocks_given[stage] and ch.source[stage] != f"blocks.{stage}":
        where = next(iter(ch.section_params[stage])).split(".")[0]  # the section the user wrote
    return params, where


def _resolve_context(scenario: Any, chosen: Mapping[str, Block]) -> ResolveContext:
    return ResolveContext(
        pad_size_m=scenario.platform.pad_size_m,
        pad_height_m=scenario.platform.pad_height_m,
        mitigation=scenario.perception.mitigation,
        calibration=scenario.camera.calibration,
        upstream={stage: b.spec for stage, b in chosen.items()},
    )


def _load_camera(block: Block, where: str, fresh: bool) -> CameraModel:
    try:
        model: CameraModel = block.spec.build(block.params, CameraLoad(fresh=fresh))
    except ValueError as err:  # "calibration: ..." from the camera's factory
        raise ValueError(f"{where}.{err}") from None
    return model


def resolve_blocks(scenario: Any, *, load_camera: bool = True, fresh_camera: bool = False) -> EffectiveBlocks:
    """The effective blocks of ``scenario`` (preset, then the per-block sections, then ``blocks:``).

    Raises ``ValueError`` with one line naming the scenario key for an unknown name, an unknown or
    rejected parameter, or an incompatible pair of blocks."""
    preset = preset_data(scenario.preset)
    ch = _preset_choices(scenario.preset, preset)
    _scenario_choices(scenario, ch)
    chosen: dict[str, Block] = {}
    wheres: dict[str, str] = {}
    camera_model = None
    for stage in STAGES:
        spec = block_spec(stage, ch.names[stage], ch.source[stage])
        params, where = _given_params(stage, spec, ch)
        values = spec.context_values(_resolve_context(scenario, chosen))
        block = Block(stage, spec.name, spec.make_params(params, values, where), params, spec)
        chosen[stage], wheres[stage] = block, where
        if stage == "camera" and load_camera:
            camera_model = _load_camera(block, where, fresh_camera)
    color_needed = any(b.spec.needs.get("camera.color") == (True,) for b in chosen.values())
    color = color_needed if scenario.camera.color is None else bool(scenario.camera.color)
    check_compatibility(chosen, ch.source, color=color, level_pad=scenario.platform.sea is None)
    if load_camera:
        # a geolocator validates its parameters in its constructor (cheap): run it now, not in flight
        g = chosen["geolocator"]
        where = ch.source["geolocator"].split(" (preset")[0]
        try:
            g.spec.build(g.params, MountedCamera(camera=camera_model, mount=CameraMount.downward()))
        except (ValueError, TypeError) as err:
            raise ValueError(f"{where}: geolocator '{g.name}' rejects its parameters: {err}") from None
    return EffectiveBlocks(scenario.preset, chosen, dict(preset.get("mission", {})), camera_model, color)


def check_compatibility(
    chosen: Mapping[str, Block], source: Mapping[str, str], *, color: bool, level_pad: bool = True
) -> None:
    """Every block's ``needs`` against the other choices' names and ``provides``; the first mismatch
    raises ``ValueError`` naming the key of the block whose need is not met. ``level_pad``: the pad is
    level and at a fixed height (False on a ship's deck, ``platform.sea``), which a geolocator that
    intersects rays with a horizontal plane needs (``platform.level``)."""
    uses_image = bool(chosen["detector"].spec.provides.get("image", True))
    for stage in STAGES:
        block = chosen[stage]
        for need, allowed in block.spec.needs.items():
            other_stage, _, feature = need.partition(".")
            if need == "platform.level":
                if level_pad not in allowed:
                    where = source[stage].split(" (preset")[0]
                    raise ValueError(
                        f"{where}: {stage} '{block.name}' assumes a level pad at a fixed height, not a"
                        " ship's deck that tilts and heaves (platform.sea): use the pnp geolocator"
                    )
                continue
            other = chosen[other_stage]
            if not feature:
                ok = other.name in allowed
                what = f"{other_stage} '{other.name}'"
                want = f"{other_stage} {' or '.join(map(str, allowed))}"
            elif other_stage == "camera" and feature == "color":
                if not uses_image:
                    continue
                ok = color
                what = "a grey camera (camera.color: false)"
                want = "a colour camera"
            else:
                offered = other.spec.provides.get(feature)
                offered_t = offered if isinstance(offered, tuple) else (offered,)
                ok = any(v in allowed for v in offered_t)
                what = f"{other_stage} '{other.name}' (gives {feature} {'/'.join(map(str, offered_t))})"
                want = f"{other_stage} {feature} {' or '.join(map(str, allowed))}"
            if not ok:
                where = source[stage].split(" (preset")[0]
                raise ValueError(
                    f"{where}: {stage} '{block.name}' needs {want}, not {what} ({source[other_stage]})"
                )


def describe_blocks() -> str:
    """The text of ``alight blocks``: every block with its parameters and what it works with."""
    lines: list[str] = []
    for stage in STAGES:
        lines.append(f"{stage}:")
        for name, spec in BLOCKS[stage].items():
            lines.append(f"  {name}: {spec.summary}")
            if spec.needs:
                needs = "; ".join(f"{k} in {list(v)}" for k, v in spec.needs.items())
                lines.append(f"    works with: {needs}")
            if spec.provides:
                lines.append(f"    provides: {', '.join(f'{k}={v}' for k, v in spec.provides.items())}")
            for pname, default, doc in spec.parameters():
                ctx = spec.context.get(pname)
                shown = f"from {ctx}" if ctx is not None and default is None else repr(_plain(default))
                lines.append(f"    {pname} = {shown}" + (f"  # {doc}" if doc else ""))
    lines.append("presets: " + ", ".join(preset_names()))
    return "\n".join(lines)


def compatible_pairs() -> list[tuple[str, str, str, str]]:
    """Every pair of blocks whose ``needs`` name a stage: (stage, name, other stage, other name)."""
    out = []
    for stage in STAGES:
        for spec in BLOCKS[stage].values():
            for need, allowed in spec.needs.items():
                other_stage, _, feature = need.partition(".")
                if other_stage not in BLOCKS:
                    continue
                for other in BLOCKS[other_stage].values():
                    if feature:
                        v = other.provides.get(feature)
                        vt = v if isinstance(v, tuple) else (v,)
                        if not any(x in allowed for x in vt):
                            continue
                    elif other.name not in allowed:
                        continue
                    out.append((stage, spec.name, other_stage, other.name))
    return out
