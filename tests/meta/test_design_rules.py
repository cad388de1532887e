"""Design rules of issue 35 that the code can check by itself: no import cycle between alight's modules,
no function a reader cannot hold (over 80 lines, numba kernels excepted when they say why they are one),
and no capability test by ``getattr``/``hasattr`` on alight's own objects (a declared Protocol or a typed
field says what a block can do).

Each rule lists what still breaks it (``PENDING_*``), so that the list can only shrink: a new breach fails,
and an entry that no longer breaks the rule fails too until it is taken off the list."""

from __future__ import annotations

import ast
from pathlib import Path

SRC = Path(__file__).resolve().parents[2] / "src" / "alight"
MAX_FUNCTION_LINES = 80

# Functions over 80 lines that the redesign has not split yet (module path relative to src/alight, name).
PENDING_LONG: set[tuple[str, str]] = set()
# numba kernels over 80 lines without a comment saying why they are one kernel
PENDING_LONG_KERNELS: set[tuple[str, str]] = set()
# ``hasattr(x, "name")`` / ``getattr(x, "name", default)`` on alight's own objects, still to be replaced by a
# Protocol or a typed field: (module, attribute name). Calls on objects that are not alight's (pymavlink
# messages, rosbags and pyulog records, os, numba, PyYAML's exceptions, thread-locals) carry a
# ``# third-party`` comment on the line or are listed in THIRD_PARTY with what the object is.
PENDING_CAPABILITY_CHECKS: set[tuple[str, str]] = set()


THIRD_PARTY: dict[tuple[str, str], str] = {
    ("campaign/engines.py", "box"): "a threading.local that may not hold the worker's sandbox yet",
    ("campaign/engines.py", "key"): "a threading.local that may not hold the worker's key yet",
    ("evaluation/qos_profile.py", "getloadavg"): "os: not on every platform",
    ("interfaces/mavlink_bridge.py", "fileno"): "pymavlink's connection port",
    ("interfaces/mavlink_bridge.py", "port"): "pymavlink's connection object (UDP or serial)",
    ("interfaces/mavlink_bridge.py", "reset_counter"): "a pymavlink ODOMETRY message (MAVLink 2)",
    ("interfaces/mavlink_bridge.py", "signal_quality"): "a pymavlink DISTANCE_SENSOR (MAVLink 2)",
    ("interfaces/replay_readers.py", "file_corruption"): "pyulog's ULog (attribute of newer releases)",
    ("interfaces/replay_readers.py", "header"): "a message deserialised by rosbags",
    ("interfaces/replay_readers.py", "stamp"): "a message deserialised by rosbags",
    ("interfaces/replay_readers.py", "sec"): "a rosbags time stamp",
    ("interfaces/replay_readers.py", "nanosec"): "a rosbags time stamp (ROS 2; ROS 1 has nsec)",
    ("interfaces/sitl.py", "position_valid"): "a pymavlink LANDING_TARGET message (MAVLink 2 field)",
    ("interfaces/sitl.py", "mission_type"): "a pymavlink MISSION_REQUEST_LIST (MAVLink 2 field)",
    ("compile/meter.py", "n"): "a threading.local depth counter",
}
# Import cycles the redesign has not broken yet (each a sorted list of module names).
PENDING_CYCLES: list[list[str]] = []


def _modules() -> dict[str, ast.Module]:
    return {str(p.relative_to(SRC)): ast.parse(p.read_text(), str(p)) for p in sorted(SRC.rglob("*.py"))}


def _module_name(rel: str) -> str:
    parts = ["alight", *Path(rel).with_suffix("").parts]
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _is_type_checking(node: ast.If) -> bool:
    return isinstance(node.test, ast.Name | ast.Attribute) and "TYPE_CHECKING" in ast.unparse(node.test)


def _imports(tree: ast.Module, this: str, is_package: bool) -> set[str]:
    """Every alight module this module imports, at the top or inside a function (not under TYPE_CHECKING)."""
    out: set[str] = set()
    base = this if is_package else this.rpartition(".")[0]

    def visit(node: ast.AST) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and _is_type_checking(child):
                for c in child.orelse:
                    visit(c)
                continue
            if isinstance(child, ast.Import):
                out.update(a.name for a in child.names if a.name.startswith("alight"))
            elif isinstance(child, ast.ImportFrom):
                if child.level:
                    pkg = base.rsplit(".", child.level - 1)[0] if child.level > 1 else base
                    mod = f"{pkg}.{child.module}" if child.module else pkg
                else:
                    mod = child.module or ""
                if mod.startswith("alight"):
                    out.add(mod)
                    out.update(f"{mod}.{a.name}" for a in child.names)
            visit(child)

    visit(tree)
    return out


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []

    def strong(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph[v]:
            if w not in index:
                strong(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            strong(v)
    return out


def test_no_import_cycle_between_modules() -> None:
    trees = _modules()
    names = {_module_name(rel): rel for rel in trees}
    graph: dict[str, set[str]] = {}
    for name, rel in names.items():
        deps = _imports(trees[rel], name, rel.endswith("__init__.py"))
        # a package's __init__ importing its own submodules is not a cycle of design
        graph[name] = {d for d in deps if d in names and d != name and not d.startswith(name + ".")}
    assert _cycles(graph) == PENDING_CYCLES


def _is_kernel(fn: ast.FunctionDef) -> bool:
    return any("jit" in ast.unparse(d) for d in fn.decorator_list)


def _says_why_one_kernel(fn: ast.FunctionDef, source_lines: list[str]) -> bool:
    doc = ast.get_docstring(fn) or ""
    above = "\n".join(source_lines[max(0, fn.lineno - 6) : fn.lineno])
    body = "\n".join(source_lines[fn.lineno : fn.lineno + 12])
    return any("one kernel" in text.lower() for text in (doc, above, body))


def _long_functions() -> tuple[set[tuple[str, str]], set[tuple[str, str]]]:
    long_fns: set[tuple[str, str]] = set()
    long_kernels: set[tuple[str, str]] = set()
    for p in sorted(SRC.rglob("*.py")):
        rel = str(p.relative_to(SRC))
        text = p.read_text()
        lines = text.splitlines()
        for node in ast.walk(ast.parse(text)):
            if not isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                continue
            n_lines = (node.end_lineno or node.lineno) - node.lineno + 1
            if n_lines <= MAX_FUNCTION_LINES:
                continue
            if isinstance(node, ast.FunctionDef) and _is_kernel(node):
                if not _says_why_one_kernel(node, lines):
                    long_kernels.add((rel, node.name))
            else:
                long_fns.add((rel, node.name))
    return long_fns, long_kernels


def test_no_function_over_80_lines() -> None:
    long_fns, long_kernels = _long_functions()
    assert long_fns - PENDING_LONG == set(), "split these functions (at most 80 lines)"
    assert PENDING_LONG - long_fns == set(), "no longer over 80 lines: take them off PENDING_LONG"
    assert long_kernels - PENDING_LONG_KERNELS == set(), "say in a comment why each is one kernel"
    assert PENDING_LONG_KERNELS - long_kernels == set(), "take them off PENDING_LONG_KERNELS"


def _capability_checks(listed_third_party: set[tuple[str, str]] | None = None) -> set[tuple[str, str]]:
    """The probing calls on alight's own objects; ``listed_third_party`` collects the THIRD_PARTY hits."""
    found: set[tuple[str, str]] = set()
    for p in sorted(SRC.rglob("*.py")):
        rel = str(p.relative_to(SRC))
        text = p.read_text()
        lines = text.splitlines()
        for node in ast.walk(ast.parse(text)):
            if not (isinstance(node, ast.Call) and isinstance(node.func, ast.Name)):
                continue
            name = node.func.id
            probing = (name == "hasattr" and len(node.args) == 2) or (
                name == "getattr" and len(node.args) == 3
            )
            if not probing or not isinstance(node.args[1], ast.Constant):
                continue
            key = (rel, str(node.args[1].value))
            if key in THIRD_PARTY and listed_third_party is not None:
                listed_third_party.add(key)
            if "# third-party" in lines[node.lineno - 1] or key in THIRD_PARTY:
                continue
            found.add(key)
    return found


def test_no_capability_checks_by_getattr_on_alights_own_objects() -> None:
    third_party: set[tuple[str, str]] = set()
    found = _capability_checks(third_party)
    assert set(THIRD_PARTY) - third_party == set(), "no such call any more: take it off THIRD_PARTY"
    assert found - PENDING_CAPABILITY_CHECKS == set(), (
        "declare the capability (a Protocol or a typed field), or mark a third-party object '# third-party'"
    )
    assert PENDING_CAPABILITY_CHECKS - found == set(), "gone: take them off PENDING_CAPABILITY_CHECKS"
