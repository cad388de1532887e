"""Scenario fuzz harness (issue 39): mutated scenario files through ``alight fly`` and the flight's build.

    PYTHONPATH=src python benchmarks/fuzz_scenarios.py [--n 1000] [--seed 0] [--limit-s 20]

prints a JSON summary. Each variant starts from one of the example scenarios (``examples/*.yaml``, and
``preset: kim_kaist``), either as its file or as its whole schema (the loaded scenario's dump, so that
every key can be hit), and gets one mutation: a value replaced by the wrong type (a string, a list, a
mapping, a boolean, null), by NaN, inf, a negative, a huge or tiny number, a 2^80 integer; a key deleted,
an unknown key added, a section nested one level deeper or flattened into a scalar; or the file's bytes
damaged (cut short, bytes flipped, random bytes, a tab, a NUL, an alias bomb, 5,000 nested brackets, a
1 MB value, a key given twice).

Each variant goes through the command line, ``alight fly FILE --print-config`` (the loader and the
blocks' resolution), and, when that accepts it, through the flight's whole build without flying
(``evaluation.runner.world_for_scenario``: the airframe, the preset's blocks and the world), each under a
watchdog (SIGALRM). Counted: ``refused`` (exit 2 and one line on stderr naming the file, or an
``AlightError`` of one line from the build), ``accepted``, and the failures: ``tracebacks`` (any other
exception), ``hangs`` (over the limit), ``not_one_line`` (a refusal of more or less than one line, or one
that does not name the file), ``non_finite_accepted`` (an accepted scenario holding a NaN or an infinite
number). The test ``tests/test_fuzz_scenarios.py`` runs a short version.
"""

from __future__ import annotations

import argparse
import contextlib
import copy
import io
import json
import math
import signal
import sys
import tempfile
import time
import warnings
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent))
from robustness_harness import _call as watchdog_call  # noqa: E402  (the harnesses' watchdog)
from robustness_harness import _on_alarm  # noqa: E402

from alight.cli import main as alight_main
from alight.errors import AlightError
from alight.evaluation.runner import world_for_scenario
from alight.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]
WARMUP_LIMIT_S = 600.0
"""The per-call limit of a preset's first build (numba compiles or loads its kernels then)."""
EXTRA_SEEDS = {"kim_kaist": "preset: kim_kaist\nplatform: {path: straight, speed_mps: 1.5}\n"}


def _call(fn: Callable[[], Any], limit_s: float) -> tuple[str, Any]:
    """The harnesses' one watchdog, with this boundary's documented refusal (AlightError)."""
    return watchdog_call(fn, limit_s, (AlightError,))


# ---- the variants ----------------------------------------------------------------------------------------


def seed_texts() -> dict[str, str]:
    """The starting files: the examples and the extra seeds, by name."""
    texts = {p.stem: p.read_text(encoding="utf-8") for p in sorted((ROOT / "examples").glob("*.yaml"))}
    return {**texts, **EXTRA_SEEDS}


def seed_trees(texts: dict[str, str], tmp: Path) -> dict[str, dict[str, Any]]:
    """Each seed's whole schema: the loaded scenario's dump (every key, with its value or null)."""
    trees = {}
    for name, text in texts.items():
        path = tmp / f"seed_{name}.yaml"
        path.write_text(text, encoding="utf-8")
        trees[name] = load_scenario(path).model_dump(mode="json")
    return trees


def _paths(node: Any, prefix: tuple[Any, ...] = ()) -> Iterator[tuple[Any, ...]]:
    """Every key path in a tree of mappings and lists (the root excluded)."""
    items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else ()
    for k, v in items:
        yield (*prefix, k)
        yield from _paths(v, (*prefix, k))


def _replace(v: Any, how: str) -> Any:
    number = v if isinstance(v, (int, float)) and not isinstance(v, bool) else 1.0
    return {
        "nan": math.nan, "inf": math.inf, "-inf": -math.inf, "negative": -abs(number) - 1.0,
        "huge": 1e308, "1e12": 1e12, "zero": 0, "tiny": 1e-300, "bigint": 2**80, "string": "x",
        "bool": True, "null": None, "list": [v, v], "mapping": {"value": v}, "empty_list": [],
        "empty_mapping": {},
    }[how]  # fmt: skip


VALUE_MUTATIONS = [
    "nan", "inf", "-inf", "negative", "huge", "1e12", "zero", "tiny", "bigint", "string", "bool", "null",
    "list", "mapping", "empty_list", "empty_mapping",
]  # fmt: skip
TREE_MUTATIONS = [*VALUE_MUTATIONS, "delete", "unknown_key", "nest_deeper", "flatten"]
TEXT_MUTATIONS = [
    "truncate", "flip_bytes", "random_bytes", "tab", "nul", "alias_bomb", "deep_nesting", "long_value",
    "duplicate_key",
]  # fmt: skip


def mutate_tree(tree: dict[str, Any], how: str, rng: np.random.Generator) -> tuple[str, str]:
    """One mutation at a random key path of a copy of ``tree``; the YAML text and the path's name."""
    data = copy.deepcopy(tree)
    paths = list(_paths(data))
    path = paths[int(rng.integers(len(paths)))]
    parent = data
    for k in path[:-1]:
        parent = parent[k]
    key = path[-1]
    if how == "delete":
        del parent[key]
    elif how == "unknown_key":
        target = parent[key] if isinstance(parent[key], dict) else parent
        if isinstance(target, dict):
            target["zz_unknown_key"] = 1
        else:  # a list: an element that is not the list's kind
            target.append({"zz_unknown_key": 1})
    elif how == "nest_deeper":
        parent[key] = {str(key): parent[key]}
    elif how == "flatten":
        leaves = [p for p in _paths(parent[key]) if not isinstance(_at(parent[key], p), (dict, list))]
        parent[key] = _at(parent[key], leaves[0]) if leaves else 7
    else:
        parent[key] = _replace(parent[key], how)
    name = ".".join(str(k) for k in path)
    return yaml.safe_dump(data, sort_keys=False, allow_unicode=True), name


def _at(node: Any, path: tuple[Any, ...]) -> Any:
    for k in path:
        node = node[k]
    return node


def mutate_text(text: str, how: str, rng: np.random.Generator) -> bytes:
    """One damage to a file's bytes."""
    raw = text.encode("utf-8")
    if how == "truncate":
        return raw[: int(rng.integers(0, max(1, len(raw))))]
    if how == "flip_bytes":
        b = bytearray(raw)
        for i in rng.integers(0, max(1, len(b)), size=int(rng.integers(1, 8))):
            if b:
                b[int(i)] = int(rng.integers(0, 256))
        return bytes(b)
    if how == "random_bytes":
        return rng.integers(0, 256, size=int(rng.integers(1, 2000)), dtype=np.uint8).tobytes()
    if how == "tab":
        return raw.replace(b"\n  ", b"\n\t", 1) if b"\n  " in raw else b"platform:\n\tpath: circle\n"
    if how == "nul":
        i = int(rng.integers(0, max(1, len(raw))))
        return raw[:i] + b"\x00" + raw[i:]
    if how == "alias_bomb":  # "billion laughs": 10^9 elements by reference
        lines = ["a0: &a0 [1, 1, 1, 1, 1, 1, 1, 1, 1, 1]"]
        lines += [f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * 10)}]" for i in range(1, 9)]
        return (text + "\nbomb: " + "\n".join(lines).replace("\n", "\n  ") + "\n").encode("utf-8")
    if how == "deep_nesting":
        return raw + b"\nplatform: " + b"[" * 5000 + b"]" * 5000 + b"\n"
    if how == "long_value":
        return raw + b"\nname: " + b"x" * 1_000_000 + b"\n"
    if how == "duplicate_key":
        first = text.splitlines()[0] if text.strip() else "preset: groundtruth"
        return (text + "\n" + first + "\n").encode("utf-8")
    raise ValueError(how)


def variants(n: int, seed: int, tmp: Path) -> Iterator[tuple[str, bytes]]:
    """``n`` variants ``(kind, file bytes)``: every mutation in turn first, then at random."""
    rng = np.random.default_rng(seed)
    texts = seed_texts()
    trees = seed_trees(texts, tmp)
    names = sorted(texts)
    kinds = [f"tree:{m}" for m in TREE_MUTATIONS] + [f"text:{m}" for m in TEXT_MUTATIONS]
    for i in range(n):
        kind = kinds[i] if i < len(kinds) else kinds[int(rng.integers(len(kinds)))]
        base = names[int(rng.integers(len(names)))]
        how = kind.partition(":")[2]
        if kind.startswith("tree:"):
            text, where = mutate_tree(trees[base], how, rng)
            yield f"{kind}:{base}:{where}", text.encode("utf-8")
        else:
            yield f"{kind}:{base}", mutate_text(texts[base], how, rng)


# ---- one variant -----------------------------------------------------------------------------------------


def _fly_print_config(path: Path) -> tuple[int, str, str]:
    """``alight fly PATH --print-config``: exit status, stdout, stderr."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = alight_main(["fly", str(path), "--print-config"])
    return status, out.getvalue(), err.getvalue()


def _non_finite(node: Any) -> bool:
    if isinstance(node, float):
        return not math.isfinite(node)
    if isinstance(node, dict):
        return any(_non_finite(v) for v in node.values())
    if isinstance(node, list):
        return any(_non_finite(v) for v in node)
    return False


class Counts:
    def __init__(self) -> None:
        self.c = {
            "variants": 0, "refused": 0, "refused_at_build": 0, "accepted": 0, "tracebacks": 0, "hangs": 0,
            "not_one_line": 0, "non_finite_accepted": 0,
        }  # fmt: skip
        self.examples: list[str] = []
        self.build_refusals: list[str] = []
        """What the loader took and the flight's build refused (one line each): not failures, but a
        check the loader could make earlier."""

    def fail(self, what: str, kind: str, detail: str = "") -> None:
        self.c[what] += 1
        self.examples.append(f"{what}:{kind}:{detail[:100]}")


def check_variant(path: Path, kind: str, counts: Counts, limit_s: float, built: set[str]) -> None:
    """The variant at ``path`` through the command line and, when accepted, the flight's build."""
    status, value = _call(lambda: _fly_print_config(path), limit_s)
    if status != "ok":
        counts.fail("hangs" if status == "hang" else "tracebacks", kind, repr(value))
        return
    code, _, err = value
    if code != 0:
        lines = err.strip().splitlines()
        if code != 2 or len(lines) != 1 or path.name not in lines[0]:
            counts.fail("not_one_line", kind, f"exit {code}: {err.strip()[:90]}")
        else:
            counts.c["refused"] += 1
        return
    scenario = load_scenario(path)
    if _non_finite(scenario.model_dump(mode="json")):
        counts.fail("non_finite_accepted", kind)
    preset = scenario.preset
    status, value = _call(
        lambda: world_for_scenario(scenario), limit_s if preset in built else WARMUP_LIMIT_S
    )
    built.add(preset)
    if status == "ok":
        counts.c["accepted"] += 1
    elif status == "refused" and len(str(value).splitlines()) == 1:
        counts.c["refused_at_build"] += 1
        counts.build_refusals.append(f"{kind}: {str(value)[:120]}")
    elif status == "refused":
        counts.fail("not_one_line", kind, str(value))
    else:
        counts.fail("hangs" if status == "hang" else "tracebacks", kind, f"{type(value).__name__}: {value}")


def run(n: int = 1000, seed: int = 0, limit_s: float = 20.0) -> dict[str, Any]:
    """The whole harness; the JSON summary as a dict."""
    signal.signal(signal.SIGALRM, _on_alarm)
    counts = Counts()
    built: set[str] = set()
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as d, warnings.catch_warnings():
        warnings.simplefilter("ignore")  # what counts is the exit and its message, not library warnings
        tmp = Path(d)
        for i, (kind, data) in enumerate(variants(n, seed, tmp)):
            path = tmp / f"variant_{i}.yaml"
            path.write_bytes(data)
            counts.c["variants"] += 1
            check_variant(path, kind, counts, limit_s, built)
            path.unlink()
    failures = sum(counts.c[k] for k in ("tracebacks", "hangs", "not_one_line", "non_finite_accepted"))
    return {
        **counts.c,
        "failures": failures,
        "seed": seed,
        "per_call_limit_s": limit_s,
        "wall_s": round(time.perf_counter() - t0, 1),
        "examples": counts.examples[:12],
        "build_refusals": counts.build_refusals[:6],
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=1000, help="variants")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--limit-s", type=float, default=20.0, help="watchdog per call (s)")
    args = parser.parse_args(argv)
    summary = run(args.n, args.seed, args.limit_s)
    print(json.dumps(summary, indent=2))
    return 0 if summary["failures"] == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
