"""Generate the reference parts of the docs from the code: ``docs/scenarios.md`` (every scenario key with
its default, from the pydantic models), ``docs/blocks.md`` (every block, its parameters, the compatible
combinations and the one-line refusal of each incompatible one) and ``examples/campaigns/blocks.yaml``
(the campaign that flies every compatible combination).

    python tools/gen_docs.py          # rewrite the files
    python tools/gen_docs.py --check  # exit 1 when a file is not up to date (tests/meta runs this)
"""

from __future__ import annotations

import re
import sys
from pathlib import Path
from typing import Any

from pydantic import BaseModel

ROOT = Path(__file__).resolve().parents[1]

SCENARIOS_HEAD = """# Scenario files

YAML, validated by `alight.scenario.Scenario` (pydantic). Unknown keys are errors; every key has a
default, so `preset`, `seed` and `platform: {path, speed_mps}` are enough. A wrong file makes
`alight fly` print one line such as

    alight fly: bad.yaml: platform.speed_mps: Input should be greater than or equal to 0, got -1.0

and exit with status 2.

**Defaults live in the blocks.** The sections `planner`, `estimator` and `controller` hold overrides
of the parameters of the scenario's planner, platform estimator and controller: `none` means the block's
default (`alight blocks` lists every block's parameters and defaults; `alight fly SCENARIO
--print-config` prints the effective ones). Setting a key the scenario's block does not have is refused
(e.g. `estimator.use_turn_rate` with `kim_kaist`, whose UKF has no turn-rate state). The `blocks`
section picks the implementations themselves; see [blocks.md](blocks.md).

**Each setting is declared once**, in the runtime configuration that uses it: the `mission` keys in
`MissionConfig` (`mission/state_machine.py`) and `GuidanceConfig` (`mission/guidance.py`),
`mission.touchdown` in `TouchdownConfig`, `platform.telemetry` in `TelemetryConfig`, `rangefinder` and
`optical_flow` in `sim/sensors.py`, `camera.distractors` in `DistractorSpec`; the other sections in
`src/alight/scenario.py`. A `mission` key left `none` flies the preset's value (listed below as
"Presets:") or else the default the table names.

This file is generated from those declarations by `python tools/gen_docs.py` (a test checks it is up to
date): edit their docstrings, not this table.

| key | default | meaning |
|---|---|---|
"""


# Meanings of the keys whose field has no docstring yet (the docstring, when there is one, wins); the
# test in tests/meta fails on a key with neither.
FALLBACK = {
    "seed": "seeds every random draw of the mission (platform start, wind, sensor noise, perception)",
    "duration_s": "the mission times out after this much simulated time",
    "platform.path": "`straight`, `circle`, `figure8` (lemniscate), `tractor` (rows joined by U-turns), "
    "`random` (smooth random curvature)",
    "platform.speed_mps": "constant speed along the path",
    "platform.pad_size_m": "side of the square pad",
    "platform.pad_height_m": "height of the pad surface above the ground",
    "platform.circle_radius_m": "circle path radius",
    "platform.figure8_length_m": "figure-8 length tip to tip",
    "platform.tractor_row_length_m": "length of the tractor path's rows",
    "platform.tractor_turn_radius_m": "radius of the tractor path's U-turns",
    "platform.random_max_curvature": "bound on the random path's curvature (1/m)",
    "wind.model": "`none`, `steady` (air velocity, drag force 0.5 rho v^2 A), `gust` (paper 004 Sec. IV-C)",
    "perception.rate_hz": "detection rate",
    "camera.gamma": "gamma of the rendered brightness",
    "camera.brightness_drift_period_s": "period of the brightness drift (s)",
    "search_area.x_min": "the area explored (m, W)",
    "search_area.x_max": "the area explored (m, W)",
    "search_area.y_min": "the area explored (m, W)",
    "search_area.y_max": "the area explored (m, W)",
    "faults": "faults injected into the detections",
    "search_area": "the area the exploration covers (m, W)",
    "mission": "the state machine and the guidance",
    "contact": "touchdown judging",
    "contact.gear_half_width_m": "landed only within the pad shrunk by this",
    "contact.max_vertical_speed_mps": "landed only below this vertical speed relative to the pad",
    "contact.max_horizontal_speed_mps": "landed only below this horizontal speed relative to the pad",
    "contact.max_tilt_deg": "landed only below this tilt",
}


def _models(annotation: Any) -> list[type]:
    """The scenario section in an annotation: a pydantic model or a settings dataclass."""
    from alight.settings import is_section

    sub = is_section(annotation)
    return [] if sub is None else [sub]


def _fmt_default(value: Any) -> str:
    if value is None:
        return "none"
    if isinstance(value, bool):
        return f"`{str(value).lower()}`"
    if isinstance(value, str):
        return f"`{value}`"
    if isinstance(value, tuple | list):
        return "(" + ", ".join(_fmt_default(v).strip("`") for v in value) + ")" if value else "[]"
    if isinstance(value, BaseModel):
        return ""
    return f"{value:g}" if isinstance(value, float) else str(value)


def _plain_roles(text: str) -> str:
    """Sphinx roles (``:class:`X```) as code: the settings dataclasses' docstrings use them."""
    return re.sub(r":(?:data|class|func|meth|attr|mod):`([^`]+)`", r"``\1``", text)


def _one_line(text: str | None) -> str:
    return " ".join(text.split()).replace("|", "\\|").replace("``", "`")


def _runtime_note(model: type, name: str, default: Any) -> str:
    """For a key of a derived section left None by default: the default of the field it comes from, and
    the packaged presets' own values (``mission:`` sections)."""
    from alight.mission.blocks import preset_names
    from alight.scenario import preset_mission_defaults
    from alight.settings import default_of, sources

    origin = sources(model).get(name)
    if origin is None or default is not None:
        return ""
    note = ""
    runtime = default_of(*origin)
    if runtime is not None:
        note = f" Default: `{_fmt_default(runtime).strip('`')}`."
    if model.__name__ in ("MissionSpec", "TouchdownSpec"):
        sets = []
        for preset in preset_names():
            values = preset_mission_defaults(preset)
            values = values.get("touchdown", {}) if model.__name__ == "TouchdownSpec" else values
            if name in values:
                sets.append(f"`{preset}` {_fmt_default(values[name]).strip('`')}")
        if sets:
            note += " Presets: " + ", ".join(sets) + "."
    return note


def combinations() -> tuple[list[dict[str, str]], list[tuple[dict[str, str], str]]]:
    """Every camera x (pad, detector) x geolocator x platform estimator, on ``falanga2017``'s other
    blocks: the compatible ones, and the incompatible ones with the line that refuses them."""
    from alight.mission.blocks import BLOCKS
    from alight.scenario import Scenario

    good: list[dict[str, str]] = []
    bad: list[tuple[dict[str, str], str]] = []
    for camera in BLOCKS["camera"]:
        for detector, dspec in BLOCKS["detector"].items():
            pads = list(dspec.needs.get("pad", ("falanga_tag",)))
            for pad in pads:
                for geolocator in BLOCKS["geolocator"]:
                    for estimator in BLOCKS["platform_estimator"]:
                        combo = {
                            "camera": camera,
                            "pad": pad,
                            "detector": detector,
                            "geolocator": geolocator,
                            "platform_estimator": estimator,
                        }
                        if detector == "groundtruth" and camera != "pinhole":
                            continue  # no image: the camera is not used, one row is enough
                        try:
                            Scenario.model_validate({"preset": "falanga2017", "blocks": combo})
                        except ValueError as err:  # pydantic's ValidationError is a ValueError
                            msg = str(err).splitlines()[1].strip().removeprefix("Value error, ")
                            bad.append((combo, msg.split(" [type=")[0]))
                        else:
                            good.append(combo)
    return good, bad


def scenario_rows(model: type | None = None, prefix: str = "") -> list[tuple[str, str, str]]:
    """(dotted key, default, meaning) of every scenario key, sections before their keys: each key's
    default and meaning are its declaration's (the settings dataclass field, ``alight.settings``)."""
    from alight.scenario import Scenario
    from alight.settings import section_fields

    model = model or Scenario
    rows: list[tuple[str, str, str]] = []
    for name, f in section_fields(model).items():
        key = f"{prefix}{name}"
        subs = _models(f.annotation)
        default = f.get_default(call_default_factory=True)
        if subs and (default is None or isinstance(default, BaseModel)):
            sub = subs[0]
            doc = f.description or sub.__doc__ or FALLBACK.get(key, "")
            rows.append((f"**`{key}`**", "none" if default is None else "", _one_line(doc)))
            rows += scenario_rows(sub, key + ".")
            continue
        shown = "required" if f.is_required() else _fmt_default(default)
        meaning = (f.description or FALLBACK.get(key) or "") + _runtime_note(model, name, default)
        rows.append((f"`{key}`", shown, _one_line(_plain_roles(meaning))))
        if subs:  # a list of entries (e.g. faults.accel_bias_steps): the keys of one entry
            rows += scenario_rows(subs[0], key + ".")
    return rows


def scenarios_md() -> str:
    lines = [SCENARIOS_HEAD.rstrip("\n")]
    lines += [f"| {k} | {d} | {m} |" for k, d, m in scenario_rows()]
    return "\n".join(lines) + "\n"


def blocks_md() -> str:
    from alight.mission.blocks import BLOCKS, STAGES, _plain, preset_data, preset_names

    out = [
        "# Blocks",
        "",
        "A scenario picks one implementation per stage in its `blocks:` section; each entry is a name or",
        "`{name: ..., <parameters>}` (a mapping without `name` sets parameters of the preset's block). A",
        "preset (`src/alight/mission/preset_data/<name>.yaml`) is a named set of these choices; the",
        "scenario's entries override it. `alight blocks` prints this list; `alight fly SCENARIO",
        "--print-config` prints what a scenario flies. Incompatible choices are refused before flying with",
        "one line naming the key and exit status 2. What goes with what is declared on each block",
        "(`needs`, `provides` in its stage's registry, e.g. `src/alight/perception/registry.py`) and",
        "checked in one place (`src/alight/mission/blocks.py`).",
        "",
        "```yaml",
        "preset: falanga2017",
        "blocks:",
        "  pad: apriltag",
        "  detector: aruco",
        "  controller: {integral_gain: 1.0}      # the preset's controller, one parameter changed",
        "```",
        "",
        "This file is generated by `python tools/gen_docs.py` from the registry (a test checks it).",
        "How each compatible combination flies (landed / flown, touchdown error, which block matters)",
        "is measured in [blocks_measured.md](blocks_measured.md).",
        "",
        "## Presets",
        "",
        "| preset | " + " | ".join(STAGES) + " |",
        "|---|" + "---|" * len(STAGES),
    ]
    for name in preset_names():
        blocks = preset_data(name)["blocks"]
        cells = []
        for stage in STAGES:
            e = blocks[stage]
            if isinstance(e, str):
                cells.append(f"`{e}`")
            else:
                params = ", ".join(f"{k}: {v}" for k, v in e.items() if k != "name")
                cells.append(f"`{e['name']}` ({params})")
        out.append(f"| `{name}` | " + " | ".join(cells) + " |")
    for stage in STAGES:
        out += ["", f"## {stage}", ""]
        for name, spec in BLOCKS[stage].items():
            out.append(f"### `{name}`")
            out.append("")
            out.append(spec.summary[0].upper() + spec.summary[1:] + ".")
            if spec.needs:
                out.append("")
                out.append(
                    "Works with: " + "; ".join(f"{k} in {list(v)}" for k, v in spec.needs.items()) + "."
                )
            if spec.provides:
                out.append("")
                out.append("Provides: " + ", ".join(f"{k} = {v}" for k, v in spec.provides.items()) + ".")
            params = spec.parameters()
            if params:
                out += ["", "| parameter | default | meaning |", "|---|---|---|"]
                for pname, default, doc in params:
                    ctx = spec.context.get(pname)
                    shown = f"from {ctx}" if ctx is not None and default is None else f"`{_plain(default)}`"
                    out.append(f"| `{pname}` | {shown} | {_one_line(doc)} |")
            out.append("")
    good, bad = combinations()
    out += [
        "## Measured: the three required combinations",
        "",
        "`alight campaign examples/campaigns/blocks_acceptance.yaml --workers 1` (10 seeds per condition,",
        "branch `blocks`, 2026-11-26): every mission landed.",
        "",
        "| blocks | platform | landed | median touchdown error (m) |",
        "|---|---|---|---|",
        "| pinhole, AprilTag pad, `aruco`, `pnp`, `unicycle_ekf` | circle 2.0 m/s | 10/10 | 0.023 |",
        "| pinhole, AprilTag pad, `aruco`, `pnp`, `unicycle_ekf` | line 1.5 m/s | 10/10 | 0.015 |",
        "| fisheye, red target, `red`, `flat_earth`, `unicycle_ekf` | circle 2.0 m/s | 10/10 | 0.019 |",
        "| fisheye, red target, `red`, `flat_earth`, `unicycle_ekf` | line 1.5 m/s | 10/10 | 0.034 |",
        "| pinhole, cross-and-circle tag, `falanga`, `pnp`, `kim_ukf` | circle 2.0 m/s | 10/10 | 0.019 |",
        "| pinhole, cross-and-circle tag, `falanga`, `pnp`, `kim_ukf` | line 1.5 m/s | 10/10 | 0.006 |",
        "",
        "## Combinations",
        "",
        "Every camera x (pad, detector) x geolocator x platform estimator, on `falanga2017`'s controller,",
        "planner and mission. `examples/campaigns/blocks.yaml` flies each compatible one on a 2 m/s circle",
        "(5 seeds); the figures come from its report (`alight campaign examples/campaigns/blocks.yaml`).",
        "",
        f"### Compatible ({len(good)})",
        "",
        "| camera | pad | detector | geolocator | platform estimator |",
        "|---|---|---|---|---|",
    ]
    out += [
        f"| {c['camera']} | {c['pad']} | {c['detector']} | {c['geolocator']} | {c['platform_estimator']} |"
        for c in good
    ]
    out += [
        "",
        f"### Incompatible ({len(bad)}), each with the line that refuses it",
        "",
        "| camera | pad | detector | geolocator | platform estimator | error |",
        "|---|---|---|---|---|---|",
    ]
    out += [
        f"| {c['camera']} | {c['pad']} | {c['detector']} | {c['geolocator']} | {c['platform_estimator']} "
        f"| {_one_line(msg)} |"
        for c, msg in bad
    ]
    return "\n".join(out) + "\n"


def blocks_campaign() -> str:
    import yaml

    good, _ = combinations()
    sets = [{"name": "-".join(c.values()), "preset": "falanga2017", "blocks": c} for c in good]
    head = (
        "# Every compatible combination of camera x (pad, detector) x geolocator x platform estimator\n"
        "# (docs/blocks.md), on falanga2017's controller, planner and mission, flying a 2 m/s circle on\n"
        "# 5 seeds. Generated by tools/gen_docs.py.\n"
        "#\n"
        "#   alight campaign examples/campaigns/blocks.yaml --out runs/blocks\n"
    )
    body = {
        "name": "blocks",
        "description": "every compatible block combination on a 2 m/s circle",
        "base": {"platform": {"path": "circle", "speed_mps": 2.0}, "perception": {"rate_hz": 20.0}},
        "presets": sets,
        "seeds_per_condition": 5,
        "seed": 14000,
        "timeout_s": 900.0,
    }
    return head + yaml.safe_dump(body, sort_keys=False, width=110)


FILES = {
    "docs/scenarios.md": scenarios_md,
    "docs/blocks.md": blocks_md,
    "examples/campaigns/blocks.yaml": blocks_campaign,
}


def main(argv: list[str]) -> int:
    stale = []
    for rel, make in FILES.items():
        text = make()
        path = ROOT / rel
        if "--check" in argv:
            if not path.is_file() or path.read_text(encoding="utf-8") != text:
                stale.append(rel)
        else:
            path.write_text(text, encoding="utf-8")
    if stale:
        print(f"not up to date (run python tools/gen_docs.py): {', '.join(stale)}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.path.insert(0, str(ROOT / "src"))
    sys.exit(main(sys.argv[1:]))
