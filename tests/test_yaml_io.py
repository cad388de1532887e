"""alight.yaml_io, the one loader of the configuration files: a key given twice, bad YAML, an empty, missing
or non-UTF-8 file each become one ConfigError line, the same for scenarios, airframes and device profiles."""

from __future__ import annotations

from pathlib import Path

import pytest

from alight.airframes import read_airframe_file
from alight.energy.compute import DeviceProfile
from alight.errors import ConfigError
from alight.yaml_io import load_yaml_text, read_yaml_file


def test_a_key_given_twice_is_refused_with_its_line() -> None:
    with pytest.raises(ConfigError, match=r"^f.yaml: not valid YAML \(line 3\): .*key 'a' given twice"):
        load_yaml_text("a: 1\nb: 2\na: 3\n", "f.yaml")
    assert load_yaml_text("a: 1\nb: {a: 2}\n", "f.yaml") == {"a": 1, "b": {"a": 2}}  # other mappings


def test_an_empty_document_is_refused_unless_allowed() -> None:
    with pytest.raises(ConfigError, match=r"the file is empty \(write \{\} for a scenario"):
        load_yaml_text("# only a comment\n", "s.yaml")
    assert load_yaml_text("", "a.yaml", "airframe", allow_empty=True) is None


def test_missing_unreadable_and_non_utf8_files(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match=r"nope.yaml: no such campaign file$"):
        read_yaml_file(tmp_path / "nope.yaml", "campaign")
    bad = tmp_path / "bad.yaml"
    bad.write_bytes(b"a: \xff\xfe\n")
    with pytest.raises(ConfigError, match=r"bad.yaml: not valid YAML: not UTF-8 text"):
        read_yaml_file(bad, "scenario")
    good = tmp_path / "good.yaml"
    good.write_text("a: [1, 2]\n", encoding="utf-8")
    assert read_yaml_file(good, "scenario") == ({"a": [1, 2]}, "a: [1, 2]\n")


def test_airframes_and_device_profiles_refuse_a_key_given_twice(tmp_path: Path) -> None:
    # before, these two kept the second value silently (yaml.safe_load)
    frame = tmp_path / "frame.yaml"
    frame.write_text("name: x\nname: y\n", encoding="utf-8")
    with pytest.raises(ConfigError, match=r"^airframe .*frame.yaml: not valid YAML \(line 2\)"):
        read_airframe_file(frame)
    device = tmp_path / "device.yaml"
    device.write_text("name: x\nname: y\n", encoding="utf-8")
    with pytest.raises(ConfigError, match=r"device.yaml: not valid YAML \(line 2\)"):
        DeviceProfile.load(device)
