"""Project-level contracts: the README's commands, CI, and the direction of imports."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SRC = ROOT / "src" / "alight"

# Pipeline stages may import only what is upstream of them and the shared models (DESIGN.md).
PIPELINE_PACKAGES = ("perception", "estimation", "planning", "control", "mission")
FORBIDDEN_FOR_PIPELINE = ("alight.sim", "alight.evaluation", "alight.cli", "matplotlib", "plotly")
FORBIDDEN_FOR_SIM = (
    "alight.perception",
    "alight.estimation",
    "alight.planning",
    "alight.control",
    "alight.mission",
    "alight.evaluation",
)


def _readme_commands() -> list[str]:
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    return re.findall(r"```bash\n(.+?)\n```", text)


def test_readme_starts_with_the_two_commands() -> None:
    commands = _readme_commands()
    assert len(commands) >= 2
    assert "pip install" in commands[0] and "alight fly" in commands[0] and "--out" in commands[0]
    assert "pytest" in commands[1]


def test_ci_runs_exactly_the_readme_test_command() -> None:
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8").splitlines()
    assert _readme_commands()[1] in ci


def _imports(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
    return names


@pytest.mark.parametrize("package", PIPELINE_PACKAGES)
def test_pipeline_never_imports_the_simulator_or_plots(package: str) -> None:
    for path in (SRC / package).rglob("*.py"):
        bad = {n for n in _imports(path) if n.startswith(FORBIDDEN_FOR_PIPELINE)}
        assert not bad, f"{path.relative_to(ROOT)} imports {sorted(bad)}"


# The world of a mission and its fused 1 kHz loop run the vehicle's own low level, the autopilot's body-rate
# loop and mixer, inside the physics (as a real autopilot runs it beside the rotors): those two modules only.
SIM_LOW_LEVEL = {"world.py": {"alight.control.rate"}, "physics.py": {"alight.control.mixer"}}


def test_simulator_never_imports_the_pipeline() -> None:
    for path in (SRC / "sim").rglob("*.py"):
        bad = {n for n in _imports(path) if n.startswith(FORBIDDEN_FOR_SIM)}
        if path.parent == SRC / "sim":
            bad -= SIM_LOW_LEVEL.get(path.name, set())
        assert not bad, f"{path.relative_to(ROOT)} imports {sorted(bad)}"


def test_license_is_mit() -> None:
    assert (ROOT / "LICENSE").read_text(encoding="utf-8").startswith("MIT License")


def test_trusted_ego_state_matches_the_checked_one() -> None:
    import numpy as np

    from alight.types import EgoState

    p, v, w, a = np.arange(3.0), np.ones(3), np.zeros(3), np.full(3, 2.0)
    q = np.array([0.0, 0.0, np.sin(0.3), np.cos(0.3)])
    checked = EgoState(1.5, p, v, q, w, a)
    fast = EgoState.trusted(1.5, p, v, q, w, a)
    for name in ("p_WB", "v_WB", "q_WB", "w_WB_B", "a_WB"):
        np.testing.assert_array_equal(getattr(checked, name), getattr(fast, name))
        assert not getattr(fast, name).flags.writeable
    p[0] = 99.0  # the message keeps its own copy
    assert fast.p_WB[0] == 0.0 and fast.t == checked.t


def test_test_file_names_are_unique() -> None:
    # Test folders have no __init__.py, so pytest imports test files by basename: two files with the
    # same name in different folders break collection on a fresh checkout.
    names = [p.name for p in (ROOT / "tests").rglob("test_*.py")]
    assert len(names) == len(set(names)), sorted(n for n in names if names.count(n) > 1)


def test_trusted_reference_matches_the_checked_one() -> None:
    import numpy as np

    from alight.types import Reference

    p, v, a, j = np.arange(3.0), np.ones(3), np.zeros(3), np.full(3, 2.0)
    checked = Reference(0.5, p, v, a, j, 0.1, 0.2)
    fast = Reference.trusted(0.5, p, v, a, j, 0.1, 0.2)
    for name in ("p", "v", "a", "j"):
        np.testing.assert_array_equal(getattr(checked, name), getattr(fast, name))
        assert not getattr(fast, name).flags.writeable
    p[0] = 99.0
    assert fast.p[0] == 0.0 and (fast.yaw, fast.yaw_rate) == (checked.yaw, checked.yaw_rate)


def test_trusted_command_matches_the_checked_one() -> None:
    import numpy as np

    from alight.types import Command

    w = np.array([0.1, -0.2, 0.3])
    checked = Command(2.0, 9.5, w)
    fast = Command.trusted(2.0, 9.5, w)
    assert (fast.t, fast.thrust_N, fast.motors_off) == (checked.t, checked.thrust_N, checked.motors_off)
    np.testing.assert_array_equal(fast.w_WB_B_cmd, checked.w_WB_B_cmd)
    w[0] = 99.0
    assert fast.w_WB_B_cmd[0] == 0.1 and not fast.w_WB_B_cmd.flags.writeable


def test_packed_messages_match_the_checked_ones() -> None:
    import numpy as np

    from alight.types import EgoState, PlatformEstimate, Reference

    q = np.array([0.0, 0.0, np.sin(0.3), np.cos(0.3)])
    packed = np.concatenate([np.arange(3.0), np.ones(3), q, np.zeros(3), np.full(3, 2.0)])
    fast = EgoState.from_packed(1.5, packed.copy())
    checked = EgoState(1.5, packed[0:3], packed[3:6], q, packed[10:13], packed[13:16])
    for name in ("p_WB", "v_WB", "q_WB", "w_WB_B", "a_WB"):
        np.testing.assert_array_equal(getattr(checked, name), getattr(fast, name))
        assert not getattr(fast, name).flags.writeable
    # A message built from a packed message's fields shares them (read-only views of an owned base).
    est = PlatformEstimate(0.0, fast.p_WB, fast.v_WB, fast.a_WB, 0.0, np.eye(3), 0.0)
    assert est.p_WP is fast.p_WB
    pvaj = np.arange(12.0).reshape(4, 3)
    ref = Reference.from_packed(0.5, pvaj.copy(), 0.1, 0.2)
    checked_ref = Reference(0.5, pvaj[0], pvaj[1], pvaj[2], pvaj[3], 0.1, 0.2)
    for name in ("p", "v", "a", "j"):
        np.testing.assert_array_equal(getattr(checked_ref, name), getattr(ref, name))
        assert not getattr(ref, name).flags.writeable


# The shared numerics are a leaf: cameras, perception, estimation, planning and campaign all use them, so
# they may import only the shared message types and errors (and never a package that uses them).
ALLOWED_FOR_NUMERICS = ("alight.types", "alight.errors", "alight.numerics")


def test_numerics_is_a_leaf() -> None:
    for path in (SRC / "numerics").rglob("*.py"):
        bad = {n for n in _imports(path) if n.startswith("alight") and not n.startswith(ALLOWED_FOR_NUMERICS)}
        assert not bad, f"{path.relative_to(ROOT)} imports {sorted(bad)}"
