"""The documentation names only what exists: every file path, `alight` command and scenario key written in
the README, docs/ and the subpackage READMEs is checked against the repository, the command-line parser
and the scenario schema. A renamed file, a removed command or a scenario key that moved fails here
instead of misleading a reader."""

from __future__ import annotations

import re
import subprocess
from functools import cache
from pathlib import Path
from typing import Any

import pytest
from pydantic import TypeAdapter

ROOT = Path(__file__).resolve().parents[2]
DOCS = [
    ROOT / "README.md",
    *sorted((ROOT / "docs").glob("*.md")),
    *sorted((ROOT / "src" / "alight").rglob("README.md")),
]
# Files that alight writes (a mission's or a campaign's outputs) or that other tools write (OCamCalib's
# calibration, a vendor's measurement notes quoted as a source): named in the docs, never in the repository.
OUTPUT_NAMES = {
    "result.json",
    "scenario.yaml",
    "log.csv",
    "log_detections.csv",
    "frames.csv",
    "report.html",
    "summary.json",
    "results.csv",
    "views.txt",
    "error.txt",
    "campaign.lock.json",
    "calib_results.txt",
    "Efficiency_Graphing.md",
}
FILE_REF = re.compile(r"`([^`\s]+\.(?:py|yaml|yml|md|json|csv|html|png|txt|toml))`")
COMMAND_REF = re.compile(r"(?:`|^ *|&& )alight ([a-z][a-z_-]+)", re.MULTILINE)  # code, not prose
PLACEHOLDER = re.compile(
    r"[*<>{}$]|\b(NAME|PRESET|FILE|DIR|SCENARIO|CAMPAIGN|LOG)\b"
)  # `preset_data/NAME.yaml`
KEY_REF = re.compile(r"`([a-z_]+(?:\.[a-z_0-9]+)+)`")


@cache
def _tracked_names() -> frozenset[str]:
    out = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True).stdout
    return frozenset(Path(line).name for line in out.splitlines())


def _file_exists(ref: str, doc: Path) -> bool:
    if ref.startswith(("runs/", "out/")) or Path(ref).name in OUTPUT_NAMES:
        return True
    if "/" not in ref:
        return ref in _tracked_names() or (ROOT / ref).exists()
    bases = (ROOT, ROOT / "src" / "alight", ROOT / "src", doc.parent, ROOT / "docs", ROOT.parent)
    return any((base / ref).exists() for base in bases)


def _refs(pattern: re.Pattern[str]) -> list[tuple[str, str]]:
    return [(str(d.relative_to(ROOT)), m.group(1)) for d in DOCS for m in pattern.finditer(d.read_text())]


def test_every_file_the_docs_name_exists() -> None:
    missing = [
        (doc, ref)
        for doc, ref in _refs(FILE_REF)
        if not PLACEHOLDER.search(ref) and not _file_exists(ref, ROOT / doc)
    ]
    assert missing == []


def _commands() -> set[str]:
    from alight.cli import build_parser

    parser = build_parser()
    subs = [a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction"]
    assert subs, "alight's parser has no subcommands"
    return set(subs[0].choices)  # type: ignore[attr-defined]


def test_every_alight_command_the_docs_name_exists() -> None:
    known = _commands()
    bad = [(doc, cmd) for doc, cmd in _refs(COMMAND_REF) if cmd not in known]
    assert bad == []


@cache
def _scenario_schema() -> dict[str, Any]:
    from alight.scenario import Scenario

    return TypeAdapter(Scenario).json_schema()


def _properties(node: dict[str, Any]) -> dict[str, Any]:
    defs = _scenario_schema().get("$defs", {})
    if "$ref" in node:
        node = defs[node["$ref"].split("/")[-1]]
    for combine in ("anyOf", "allOf", "oneOf"):
        if combine in node:
            out: dict[str, Any] = {}
            for option in node[combine]:
                out.update(_properties(option))
            return out
    if "items" in node and isinstance(node["items"], dict):
        return _properties(node["items"])
    extra = node.get("additionalProperties")
    if isinstance(extra, dict) and "properties" not in node:
        return {"*": extra}
    props: dict[str, Any] = node.get("properties", {})
    return props


def _key_exists(key: str) -> bool:
    node = _scenario_schema()
    for part in key.split("."):
        props = _properties(node)
        if part in props:
            node = props[part]
        elif "*" in props:
            node = props["*"]
        else:
            return False
    return True


def test_every_scenario_key_the_docs_name_exists() -> None:
    top = set(_properties(_scenario_schema()))
    bad = []
    for doc, key in _refs(KEY_REF):
        parts = key.split(".")
        if parts[0] not in top or parts[-1] in {"py", "yaml", "md"} or any(p.startswith("_") for p in parts):
            continue  # a module (``platform.py``, ``sim.platform._arc_table``), not a key
        if not _key_exists(key):
            bad.append((doc, key))
    assert bad == []


@pytest.mark.parametrize("key", ["platform.speed_mps", "mission.land_speed_mps", "faults.odometry_jumps.t_s"])
def test_the_key_check_finds_real_keys(key: str) -> None:
    assert _key_exists(key)


def test_the_key_check_refuses_an_invented_key() -> None:
    assert not _key_exists("platform.speed_kph")
    assert not _key_exists("mission.no_such_setting")
