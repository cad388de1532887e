"""Compiling ahead in parallel processes (issue 18): the kernel list agrees with what the warm-up flights
call, the shares are balanced as worked by hand, helpers fill an empty cache, and every failure falls
back to the flight's own compile."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path
from typing import Any

import pytest

import alight.compile.parallel as pc
from alight.compile.parallel import MANIFEST, Kernel, _balanced, compile_ahead, parse_signature, read_manifest

ROOT = Path(__file__).resolve().parents[1]


def _env(**extra: str) -> dict[str, str]:
    env = dict(os.environ, **extra)
    env["PYTHONPATH"] = str(ROOT / "src") + os.pathsep + env.get("PYTHONPATH", "")
    return env


# Missions that reach what a warm-up flight once did not: a platform out of view at the end of the climb
# (exploration), the figure-8's kernels with a brake, a fast platform with telemetry (for the presets that
# fuse it).
_AFTER_WARM_UP = [
    {"duration_s": 20.0, "platform": {"path": "straight", "speed_mps": 3.0}},
    {
        "duration_s": 20.0,
        "platform": {
            "path": "figure8",
            "speed_mps": 4.0,
            "start_xy": [4.0, 1.0],
            "speed_profile": {"brake_stop": {"t_s": 6.0, "decel_mps2": 3.0, "wait_s": 1.0}},
        },
    },
    {
        "duration_s": 15.0,
        "platform": {
            "path": "straight",
            "speed_mps": 6.0,
            "telemetry": {"rate_hz": 10.0, "noise_m": 0.5, "latency_s": 0.2, "bias_m": 1.0},
        },
    },
]


@pytest.fixture(scope="module")
def warm_up_calls() -> dict[str, Any]:
    """One process flies every listed preset's warm-up in turn, recording each kernel signature the first
    time Python calls it; then, with every warm-up done, flies :data:`_AFTER_WARM_UP` with each preset
    and records what those call for the first time."""
    presets = sorted({p for k in read_manifest() for p in k.presets})
    script = textwrap.dedent(f"""
        import json
        from alight.errors import ConfigError
        from alight.evaluation.runner import run_mission
        from alight.compile.meter import python_calls
        from alight.scenario import scenario_from_dict
        from alight.compile.warmup import warm_up
        seen, after = {{}}, {{}}
        with python_calls() as calls:
            for preset in {presets!r}:
                n = len(calls)
                warm_up([preset], compile_first=False)
                seen[preset] = [c[:3] for c in calls[n:]]
            for preset in {presets!r}:
                for i, extra in enumerate({_AFTER_WARM_UP!r}):
                    n = len(calls)
                    scenario = {{"preset": preset, "seed": 3 + i, **extra}}
                    try:
                        run_mission(scenario_from_dict(scenario), record=True)
                    except ConfigError as err:  # a platform estimator without telemetry refuses it
                        assert "cannot fuse telemetry" in str(err), err
                    after[f"{{preset}} {{i}}"] = [c[:3] for c in calls[n:]]
        print(json.dumps({{"seen": seen, "after": after}}))
    """)
    out = subprocess.run(
        [sys.executable, "-c", script], env=_env(), capture_output=True, text=True, timeout=1800
    )
    assert out.returncode == 0, out.stderr[-2000:]
    result: dict[str, Any] = json.loads(out.stdout.strip().splitlines()[-1])
    return result


def test_the_kernel_list_is_what_each_presets_warm_up_flight_calls_from_python(
    warm_up_calls: dict[str, Any],
) -> None:
    # A later preset that calls a kernel signature again is not seen, so each recorded signature must
    # list at least the preset that first called it. Nothing recorded may be missing from the list, and
    # nothing listed may be stale. Regenerate with: python -m alight.compile.kernel_list --write
    listed = {(k.module, k.qualname, k.signature): k for k in read_manifest()}
    recorded = set()
    for preset, calls in warm_up_calls["seen"].items():
        for call in calls:
            key = tuple(call)
            assert key in listed, f"{preset} calls {key[0]}.{key[1]}{key[2]}, not in {MANIFEST.name}"
            assert preset in listed[key].presets, (key, preset)
            recorded.add(key)
    assert set(listed) == recorded, f"stale in {MANIFEST.name}: {sorted(set(listed) - recorded)}"


def test_after_the_warm_up_a_mission_calls_no_kernel_signature_it_did_not_load(
    warm_up_calls: dict[str, Any],
) -> None:
    # A signature first called in a mission is compiled (or loaded) on that mission's clock: seconds of
    # compile in its wall_time_s and block times, and in a campaign's timeout.
    after = warm_up_calls["after"]
    late = {m: [f"{c[0]}.{c[1]}{c[2]}" for c in calls] for m, calls in after.items() if calls}
    assert not late, f"called first after the warm-up: {late}"


def test_every_listed_signature_reads_back_as_written() -> None:
    for k in read_manifest():
        assert repr(parse_signature(k.signature)) == k.signature
    with pytest.raises(NameError):
        parse_signature("__import__('os').getcwd()")  # no builtins in the namespace
    with pytest.raises(ValueError, match="not a tuple"):
        parse_signature("float64")


def _k(name: str, cost: float, sig: str = "(float64,)") -> Kernel:
    return Kernel("m", name, sig, ("alight",), cost)


def test_shares_longest_first_onto_the_least_loaded_and_a_kernels_signatures_together() -> None:
    # Worked by hand, 2 shares: A5 -> s0 (5); B4 -> s1 (4); C3 -> s1 (7); D3 -> s0 (8); E (2 + 1,
    # two signatures, 3 in all) -> s1 (10).
    kernels = [_k("C", 3), _k("E", 2, "(int64,)"), _k("A", 5), _k("D", 3), _k("E", 1), _k("B", 4)]
    shares = _balanced(kernels, 2)
    names = [sorted({k.qualname for k in s}) for s in shares]
    assert names == [["A", "D"], ["B", "C", "E"]]
    assert sum(k.compile_s for k in shares[1]) == 10.0
    assert _balanced(kernels[:1], 4) == [[kernels[0]]]  # no empty share


def test_helpers_fill_an_empty_cache_and_a_filled_one_starts_none(tmp_path: Path) -> None:
    # Two cheap kernels of the list, compiled by two helpers into an empty cache; then nothing is left
    # to do. Run in a child process whose numba cache is the empty directory.
    if pc._cores() < 2:
        pytest.skip("one core: compile_ahead starts no helper, by design")
    cheap = sorted((k for k in read_manifest() if "alight" in k.presets), key=lambda k: k.compile_s)[:2]
    small = tmp_path / "kernels.json"
    small.write_text(json.dumps({"kernels": [{**k.__dict__, "presets": list(k.presets)} for k in cheap]}))
    # The same two kernels with a signature they cannot be compiled for: the helpers say so, one line each.
    wrong = tmp_path / "wrong.json"
    wrong.write_text(
        json.dumps(
            {
                "kernels": [
                    {**k.__dict__, "presets": list(k.presets), "signature": "(unicode_type,)"} for k in cheap
                ]
            }
        )
    )
    script = textwrap.dedent(f"""
        import json
        from pathlib import Path
        from alight.compile.parallel import _cached, compile_ahead, read_manifest
        kernels = read_manifest(Path({str(small)!r}))
        before = [_cached(k) for k in kernels]
        first = compile_ahead(["alight"], max_helpers=2, kernels_file=Path({str(small)!r}))
        after = [_cached(k) for k in kernels]
        filled = compile_ahead(["alight"], max_helpers=2, kernels_file=Path({str(small)!r}))
        second = compile_ahead(["alight"], max_helpers=2, kernels_file=Path({str(wrong)!r}))
        print(json.dumps([before, first.helpers, first.kernels, first.failed, after, filled.helpers,
                          second.helpers, second.failed, first.spans, first.peak_mib]))
    """)
    env = _env(NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    out = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    before, helpers, n, failed, after, filled, again, wrong_failed, spans, peak_mib = json.loads(
        out.stdout.strip().splitlines()[-1]
    )
    assert before == [False, False] and (helpers, n, failed) == (2, 2, [])
    assert after == [True, True] and filled == 0
    if sys.platform == "linux":
        assert peak_mib > 50.0  # a helper says its peak memory (numba and LLVM alone hold more)
    # They ran at once: each had its share before either finished (a first version handed the second
    # helper its share only once the first had ended, and compiled no faster than one process).
    assert len(spans) == 2 and max(read for read, _ in spans) < min(done for _, done in spans)
    assert again == 2 and len(wrong_failed) == 2
    for line, k in zip(sorted(wrong_failed), sorted(cheap, key=lambda k: k.name), strict=True):
        assert re.match(rf"{re.escape(k.name)}: \w*Error: \S", line), line  # e.g. numba's TypingError


def test_a_missing_or_broken_list_and_a_bad_entry_fall_back_to_the_flight(tmp_path: Path) -> None:
    none = compile_ahead(["alight"], kernels_file=tmp_path / "absent.json")
    assert none.helpers == 0 and none.note.startswith("no kernel list")
    broken = tmp_path / "broken.json"
    broken.write_text('{"kernels": [{"module": "x"}]}')
    assert compile_ahead(["alight"], kernels_file=broken).note.startswith("no kernel list")
    # A kernel that does not exist counts as cached (the safe answer): no helper is started for it.
    bad = tmp_path / "bad.json"
    entry = {"module": "alight.nowhere", "qualname": "k", "signature": "(float64,)", "presets": ["alight"]}
    bad.write_text(json.dumps({"kernels": [{**entry, "compile_s": 1.0}, {**entry, "compile_s": 2.0}]}))
    report = compile_ahead(["alight"], kernels_file=bad, max_helpers=2)
    assert report.helpers == 0 and report.failed == []


def test_helpers_one_per_core_bounded_by_the_cap_and_the_memory(monkeypatch: pytest.MonkeyPatch) -> None:
    per = pc.HELPER_MEMORY_MIB
    monkeypatch.setattr(pc, "_cores", lambda: 16)
    monkeypatch.setattr(pc, "_available_mib", lambda: None)
    assert pc.helper_count() == pc.MAX_HELPERS == 8  # the cap
    assert pc.helper_count(3) == 3
    monkeypatch.setattr(pc, "_available_mib", lambda: 2.5 * per)
    assert pc.helper_count() == 2  # what the memory holds
    monkeypatch.setattr(pc, "_available_mib", lambda: 1.5 * per)
    monkeypatch.setattr(pc, "_cores", lambda: 4)
    report = compile_ahead(["alight"])
    assert report.helpers == 0 and "memory for one helper" in report.note


def test_a_cache_directory_that_cannot_be_written_compiles_ahead_without_the_lock(tmp_path: Path) -> None:
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    entered = False
    with pc._exclusive(blocker / "cache"):  # mkdir under a file fails: no lock, no error
        entered = True
    assert entered


def test_a_helper_ends_when_its_parent_is_killed(tmp_path: Path) -> None:
    """A parent killed outright (no cleanup runs) leaves no helper compiling for nobody: the helper, on an
    empty cache with kernels that take most of a minute to compile, ends within a second or two (without
    the watch it compiled on, re-parented, for up to HELPER_TIMEOUT_S)."""
    import time

    share = tmp_path / "share.json"
    slowest = sorted(read_manifest(), key=lambda k: -k.compile_s)[:6]  # ~50 s of compile on one core
    share.write_text(json.dumps([k.__dict__ for k in slowest]), encoding="utf-8")
    parent_code = textwrap.dedent(
        f"""
        import subprocess, sys, time
        cmd = [sys.executable, "-m", "alight.compile.parallel", "--helper", {str(share)!r}]
        print(subprocess.Popen(cmd).pid, flush=True)
        time.sleep(60)
        """
    )
    env = _env(NUMBA_CACHE_DIR=str(tmp_path / "numba-cache"))
    with subprocess.Popen(
        [sys.executable, "-c", parent_code], stdout=subprocess.PIPE, text=True, env=env
    ) as parent:
        assert parent.stdout is not None
        helper_pid = int(parent.stdout.readline())
        time.sleep(1.5)  # the helper is importing or compiling
        parent.kill()
    deadline = time.monotonic() + 10.0
    alive = True
    while alive and time.monotonic() < deadline:
        time.sleep(0.2)
        try:  # ended: gone, or a zombie its new parent has not reaped yet
            alive = Path(f"/proc/{helper_pid}/stat").read_text().split(")")[-1].split()[0] != "Z"
        except OSError:
            alive = False
    if alive:
        os.kill(helper_pid, 9)
    assert not alive, "the helper outlived its killed parent by 10 s"
