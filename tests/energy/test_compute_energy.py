"""Compute energy from CPU time on a device power profile: loading and validating the profiles, and the
energy arithmetic on numbers where the answer is known in closed form."""

from __future__ import annotations

from pathlib import Path

import pytest

from alight.energy.compute import (
    HOST_MIPS_1T,
    DeviceProfile,
    available_devices,
    compute_energy_J,
    device_cpu_s,
    profile_summary,
)
from alight.errors import ConfigError


def _profile_dict(**mode_overrides: object) -> dict:
    mode = {"cores": 4, "cpu_freq_MHz": 1000, "idle_W": 2.0, "active_W": 6.0, "cpu_mips_1t": 1000}
    mode.update(mode_overrides)
    return {"name": "toy", "description": "", "cpu": "x", "default_mode": "m", "modes": {"m": mode}}


def test_shipped_profiles_load_with_sources() -> None:
    assert {"jetson_nano", "odroid_xu4"} <= set(available_devices())
    for name in available_devices():
        prof = DeviceProfile.load(name)
        assert prof.name == name and prof.sources, name
        for m in prof.modes.values():
            assert m.active_W > m.idle_W > 0 and m.cores >= 1 and m.cpu_mips_1t > 0
        assert prof.mode() is prof.modes[prof.default_mode]


def test_jetson_nano_modes_match_the_data_sheet() -> None:
    """NVIDIA's nvpmodel table: 10 W = 4 cores at 1479 MHz, 5 W = 2 cores at 918 MHz; the 10 W mode's
    busy core is (4.4 - 1.9) / 4 W; the 5 W mode spends less energy per unit of work (slower clock,
    lower voltage) but takes longer."""
    nano = DeviceProfile.load("jetson_nano")
    m10, m5 = nano.mode("10W"), nano.mode("5W")
    assert (m10.cores, m10.cpu_freq_MHz, m5.cores, m5.cpu_freq_MHz) == (4, 1479, 2, 918)
    assert m10.busy_core_W == pytest.approx(0.625)
    assert m5.cpu_time_factor() > m10.cpu_time_factor()
    e10 = compute_energy_J(1.0, nano, "10W")
    e5 = compute_energy_J(1.0, nano, "5W")
    assert e5 < e10
    assert nano.mode() is m10


def test_energy_arithmetic_is_exact() -> None:
    """1 busy core adds (6 - 2) / 4 = 1 W; a host twice as fast makes 3 host seconds 6 device seconds:
    6 J; the idle board over 10 s adds 2 W x 10 s."""
    prof = DeviceProfile.from_dict(_profile_dict())
    assert prof.mode().busy_core_W == 1.0
    assert device_cpu_s(3.0, prof, host_mips_1t=2000.0) == 6.0
    assert compute_energy_J(3.0, prof, host_mips_1t=2000.0) == 6.0
    assert compute_energy_J(3.0, prof, host_mips_1t=2000.0, duration_s=10.0) == 6.0  # idle not asked for
    assert compute_energy_J(3.0, prof, host_mips_1t=2000.0, duration_s=10.0, include_idle=True) == 26.0
    assert compute_energy_J(0.0, prof, duration_s=5.0, include_idle=True) == 10.0
    # linear in the CPU time, and the default host rating is the reference host's
    assert compute_energy_J(2.0, prof) == pytest.approx(2 * compute_energy_J(1.0, prof))
    assert compute_energy_J(1.0, prof) == pytest.approx(HOST_MIPS_1T / 1000.0)


def test_energy_rejects_bad_numbers() -> None:
    prof = DeviceProfile.from_dict(_profile_dict())
    for bad in (-1.0, float("nan"), float("inf")):
        with pytest.raises(ValueError, match="cpu_s_host"):
            compute_energy_J(bad, prof)
    with pytest.raises(ValueError, match="duration_s"):
        compute_energy_J(1.0, prof, duration_s=-1.0, include_idle=True)
    with pytest.raises(ConfigError, match="no power mode 'turbo'"):
        compute_energy_J(1.0, prof, "turbo")


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"name": "x", "modes": {}}, "missing keys"),
        ({**_profile_dict(), "colour": "red"}, "unknown keys"),
        ({**_profile_dict(), "default_mode": "other"}, "default_mode 'other'"),
        (_profile_dict(active_W=1.0), "active_W .* below idle_W"),
        (_profile_dict(cores=0), "cores must be an integer"),
        (_profile_dict(cores=2.5), "cores must be an integer"),
        (_profile_dict(idle_W="two"), "idle_W must be a positive number"),
        (_profile_dict(cpu_mips_1t=float("nan")), "cpu_mips_1t must be a positive number"),
        ({**_profile_dict(), "modes": {"m": {"cores": 4}}}, "mode 'm' is missing"),
        ({**_profile_dict(), "sources": "a string"}, "'sources' must be a list"),
        ([1, 2], "must be a mapping"),
    ],
)
def test_bad_profiles_are_config_errors(data: object, message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        DeviceProfile.from_dict(data, "bad.yaml")


def test_bad_files_name_the_file(tmp_path: Path) -> None:
    broken = tmp_path / "broken.yaml"
    broken.write_text("name: [unclosed\n", encoding="utf-8")
    with pytest.raises(ConfigError, match=r"broken\.yaml: not valid YAML"):
        DeviceProfile.load(broken)
    partial = tmp_path / "partial.yaml"
    partial.write_text("name: p\ndefault_mode: a\nmodes:\n  a: {cores: 1, idle_W: 1}\n", encoding="utf-8")
    with pytest.raises(ConfigError, match=r"partial\.yaml: mode 'a' is missing"):
        DeviceProfile.load(partial)
    with pytest.raises(ConfigError, match="not found"):
        DeviceProfile.load(tmp_path / "nope.yaml")
    with pytest.raises(ConfigError, match="unknown device 'raspberry'"):
        DeviceProfile.load("raspberry")


def test_profile_file_round_trip(tmp_path: Path) -> None:
    import yaml

    f = tmp_path / "toy.yaml"
    f.write_text(yaml.safe_dump(_profile_dict()), encoding="utf-8")
    prof = DeviceProfile.load(f)
    assert prof.mode("m").busy_core_W == 1.0
    rows = profile_summary(prof, host_mips_1t=500.0)
    assert rows == [
        {
            "device": "toy",
            "mode": "m",
            "cores": 4,
            "cpu_freq_MHz": 1000,
            "idle_W": 2.0,
            "active_W": 6.0,
            "busy_core_W": 1.0,
            "cpu_time_factor": 0.5,
        }
    ]
