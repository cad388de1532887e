"""docs/scenarios.md, docs/blocks.md and examples/campaigns/blocks.yaml are generated from the code
(tools/gen_docs.py); these tests fail when they drift, and check the scenario reference against the
pydantic models independently of the generator."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

from pydantic import BaseModel

ROOT = Path(__file__).resolve().parents[2]


def test_generated_docs_are_up_to_date() -> None:
    run = subprocess.run(
        [sys.executable, str(ROOT / "tools" / "gen_docs.py"), "--check"], capture_output=True, text=True
    )
    assert run.returncode == 0, run.stderr


def _model_keys(model: type, prefix: str = "") -> dict[str, object]:
    from alight.settings import is_section, section_fields

    out: dict[str, object] = {}
    for name, f in section_fields(model).items():
        key = prefix + name
        sub = is_section(f.annotation)
        out[key] = f.get_default(call_default_factory=True)
        if sub is not None:
            out.update(_model_keys(sub, key + "."))
    return out


def test_every_scenario_key_is_documented_with_its_default_and_nothing_else() -> None:
    from alight.scenario import Scenario

    keys = _model_keys(Scenario)
    rows = {}
    for line in (ROOT / "docs" / "scenarios.md").read_text(encoding="utf-8").splitlines():
        m = re.match(r"\| (?:\*\*)?`([\w.]+)`(?:\*\*)? \| ([^|]*) \| (.*) \|$", line)
        if m:
            rows[m.group(1)] = (m.group(2).strip(), m.group(3).strip())
    assert set(rows) == set(keys), (sorted(set(keys) - set(rows)), sorted(set(rows) - set(keys)))
    for key, default in keys.items():
        shown, meaning = rows[key]
        if isinstance(default, BaseModel):
            continue
        if default is None:
            assert shown == "none", key
        elif isinstance(default, bool):
            assert shown == f"`{str(default).lower()}`", key
        elif isinstance(default, str):
            assert shown == f"`{default}`", key
        elif isinstance(default, int | float):
            assert float(shown) == float(default), key
        assert meaning, f"{key} has no meaning in docs/scenarios.md"
