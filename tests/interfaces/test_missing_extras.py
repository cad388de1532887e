"""A missing optional dependency gives one line naming the extra to install, for every command that needs
one: ``alight sitl`` and ``alight bridge`` without pymavlink (``alight[mavlink]``), ``alight fly --mcap``
/ ``--bag`` and ``alight replay`` without the replay packages (``alight[replay]``). The missing module is
simulated: its ``sys.modules`` entry is None (import raises ModuleNotFoundError), and the alight modules
that imported it are dropped so that they import it again."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from alight.cli import main
from alight.interfaces.optional_deps import EXTRA_OF_MODULE, missing_dependency_message

ROOT = Path(__file__).resolve().parents[2]
SCENARIO = str(ROOT / "examples" / "falanga2017_straight.yaml")


def _hide(monkeypatch: pytest.MonkeyPatch, package: str) -> None:
    for name in list(sys.modules):
        if name == package or name.startswith(package + "."):
            monkeypatch.delitem(sys.modules, name)
        elif name.startswith("alight.interfaces.") and name != "alight.interfaces.optional_deps":
            monkeypatch.delitem(sys.modules, name)  # imported again, without the package
    monkeypatch.setitem(sys.modules, package, None)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("package", "extra", "argv"),
    [
        ("pymavlink", "mavlink", ["sitl", SCENARIO, "--port", "20990"]),
        ("pymavlink", "mavlink", ["bridge", "--connect", "udp:127.0.0.1:20990", "--out", "{tmp}/b"]),
        ("mcap", "replay", ["fly", SCENARIO, "--out", "{tmp}/f", "--mcap", "--no-warmup"]),
        ("rosbags", "replay", ["fly", SCENARIO, "--out", "{tmp}/f", "--bag", "{tmp}/bag", "--no-warmup"]),
        ("pyulog", "replay", ["replay", "{tmp}/flight.ulg", "--out", "{tmp}/r"]),
    ],
)
def test_a_missing_extra_is_one_line_naming_it(
    package: str, extra: str, argv: list[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:  # fmt: skip
    (tmp_path / "flight.ulg").write_bytes(b"ULog\x01\x12\x35" + bytes(64))  # a ULog header, never read
    _hide(monkeypatch, package)
    code = main([a.replace("{tmp}", str(tmp_path)) for a in argv])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert err.startswith(f"alight {argv[0]}: {package} is not installed") and f"alight[{extra}]" in err


def test_every_extra_named_exists_and_other_modules_are_not_hidden() -> None:
    import tomllib

    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["optional-dependencies"]
    assert set(EXTRA_OF_MODULE.values()) <= set(extras) and "all" in extras
    for part in ("dask", "mavlink", "replay"):  # "all" lists every optional part
        assert set(extras[part]) <= set(extras["all"])
    err = ModuleNotFoundError("No module named 'numpyy'", name="numpyy")
    assert missing_dependency_message(err) is None  # a real bug stays a traceback
