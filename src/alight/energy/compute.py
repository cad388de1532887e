"""Compute energy of the onboard software from CPU time, on a device power profile.

Paper 004 (Zamanakos et al., Sec. III) measures "the actual power consumption on the robot hardware" of
the companion computer with powprofiler. alight runs on a development machine (the *host*), so the energy
of a block on the *device* (the companion computer: Jetson Nano, ODROID-XU4) is estimated in two steps:

1. **Host CPU seconds to device CPU seconds**, by the ratio of single-thread CPU speeds::

       t_device = t_host * mips_host / mips_device

   where ``mips`` is the single-thread 7-Zip benchmark rating per CPU second (7-Zip's "R/U" total rating,
   which divides by the CPU usage, so it is a rating per CPU second like our CPU times). The device
   ratings come from published sbc-bench runs (cited in each device file), the host's from running
   ``7z b -mmt1`` on the machine that measured the CPU times (:data:`HOST_MIPS_1T` for the machine that
   measured the shipped QoS model). It is an ESTIMATE: 7-Zip is an integer / memory benchmark, and image
   filtering with wide SIMD (AVX2 on the host, 128-bit NEON on the devices) is slower still on the
   devices, so the factor is a lower bound on the slowdown of this workload.

2. **Device CPU seconds to energy**: a busy core adds ``(active_W - idle_W) / cores`` to the board's power
   (``active_W`` is the board with all ``cores`` busy, ``idle_W`` with none; linear in the number of busy
   cores)::

       E_compute = t_device * (active_W - idle_W) / cores                      [J]

   That is the energy the computation *adds*. powprofiler's model is of the *total* system energy; with
   ``include_idle=True`` the board's idle power over the flight time is added, ``idle_W * duration_s``,
   which does not depend on the quality of service (the board is on during the whole flight).

Device profiles are YAML files in ``alight/energy/devices/`` (package data), one per device, each power
mode with ``cores``, ``cpu_freq_MHz``, ``idle_W``, ``active_W``, ``cpu_mips_1t`` and the sources of the
numbers in comments and a ``sources`` list; ``DeviceProfile.load(name)`` reads one by name or path.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

from alight.errors import ConfigError
from alight.yaml_io import load_yaml_text

HOST_MIPS_1T = 2870.0
"""Single-thread 7-Zip rating per CPU second (MIPS, 7-Zip's "R/U" total) of the machine that measured the
shipped QoS model (``models/sdu_qos.yaml``, which records it too): an AMD EPYC (Zen 3, family 25 model 1)
KVM guest with 2 vCPUs; the median of five ``7z b -mmt1`` runs (7-Zip 26.02) under the shared machine's
load: 2751, 2850, 2870, 2875, 2986."""

_DEVICE_DIR = "devices"


@dataclass(frozen=True, kw_only=True)
class PowerMode:
    """One power mode of a device (see the module docstring for how the numbers are used)."""

    name: str
    """Mode name as the device file spells it (``10W``, ``5W``, ``2GHz``...)."""
    description: str
    """What the mode is (clocks, cores online)."""
    cores: int
    """CPU cores online in this mode (those ``active_W`` was measured with, all busy)."""
    cpu_freq_MHz: float
    """CPU clock of those cores (MHz)."""
    idle_W: float
    """Board power with the CPU idle (W)."""
    active_W: float
    """Board power with all ``cores`` busy (W)."""
    cpu_mips_1t: float
    """Single-thread 7-Zip rating per CPU second of one core (MIPS)."""

    def __post_init__(self) -> None:
        for name in ("cpu_freq_MHz", "idle_W", "active_W", "cpu_mips_1t"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
                raise ValueError(f"power mode {self.name!r}: {name} must be a positive number, got {v!r}")
        if isinstance(self.cores, bool) or not isinstance(self.cores, int) or self.cores < 1:
            raise ValueError(f"power mode {self.name!r}: cores must be an integer >= 1, got {self.cores!r}")
        if self.active_W < self.idle_W:
            raise ValueError(
                f"power mode {self.name!r}: active_W ({self.active_W}) is below idle_W ({self.idle_W})"
            )

    @property
    def busy_core_W(self) -> float:
        """Power one busy core adds to the idle board (W): ``(active_W - idle_W) / cores``."""
        return (self.active_W - self.idle_W) / self.cores

    def cpu_time_factor(self, host_mips_1t: float = HOST_MIPS_1T) -> float:
        """Device CPU seconds per host CPU second: ``host_mips_1t / cpu_mips_1t``."""
        if not (math.isfinite(host_mips_1t) and host_mips_1t > 0):
            raise ValueError(f"host_mips_1t must be positive, got {host_mips_1t}")
        return host_mips_1t / self.cpu_mips_1t


@dataclass(frozen=True)
class DeviceProfile:
    """A companion computer's power modes (:class:`PowerMode`) with the sources of their numbers."""

    name: str
    description: str
    cpu: str
    """The CPU core the modes refer to (e.g. ``Arm Cortex-A57``)."""
    modes: Mapping[str, PowerMode]
    default_mode: str
    sources: tuple[str, ...] = field(default=())

    def __post_init__(self) -> None:
        if not self.modes:
            raise ValueError(f"device {self.name!r} has no power modes")
        if self.default_mode not in self.modes:
            raise ValueError(
                f"device {self.name!r}: default_mode {self.default_mode!r} is not one of {sorted(self.modes)}"
            )

    def mode(self, name: str | None = None) -> PowerMode:
        """The power mode called ``name`` (the default mode when None)."""
        key = self.default_mode if name is None else name
        try:
            return self.modes[key]
        except KeyError:
            raise ConfigError(
                f"device {self.name!r} has no power mode {key!r}; modes: {sorted(self.modes)}"
            ) from None

    @classmethod
    def from_dict(cls, data: object, where: str = "<dict>") -> DeviceProfile:
        """A profile from the parsed YAML mapping (the file format of the module docstring); ``where``
        names the source in error messages. Raises :class:`alight.errors.ConfigError`."""
        if not isinstance(data, Mapping):
            raise ConfigError(f"{where}: a device profile must be a mapping, got {type(data).__name__}")
        missing = [k for k in ("name", "modes", "default_mode") if k not in data]
        if missing:
            raise ConfigError(f"{where}: missing keys {missing}")
        unknown = set(data) - {"name", "description", "cpu", "modes", "default_mode", "sources"}
        if unknown:
            raise ConfigError(f"{where}: unknown keys {sorted(unknown)}")
        modes_raw = data["modes"]
        if not isinstance(modes_raw, Mapping) or not modes_raw:
            raise ConfigError(f"{where}: 'modes' must be a non-empty mapping of mode name -> fields")
        modes: dict[str, PowerMode] = {}
        fields = ("cores", "cpu_freq_MHz", "idle_W", "active_W", "cpu_mips_1t")
        for mname, m in modes_raw.items():
            if not isinstance(m, Mapping):
                raise ConfigError(f"{where}: mode {mname!r} must be a mapping")
            lacking = [k for k in fields if k not in m]
            if lacking:
                raise ConfigError(f"{where}: mode {mname!r} is missing {lacking}")
            extra = set(m) - set(fields) - {"description"}
            if extra:
                raise ConfigError(f"{where}: mode {mname!r} has unknown keys {sorted(extra)}")
            try:
                modes[str(mname)] = PowerMode(
                    name=str(mname),
                    description=str(m.get("description", "")),
                    cores=m["cores"],
                    cpu_freq_MHz=m["cpu_freq_MHz"],
                    idle_W=m["idle_W"],
                    active_W=m["active_W"],
                    cpu_mips_1t=m["cpu_mips_1t"],
                )
            except ValueError as e:
                raise ConfigError(f"{where}: {e}") from None
        sources = data.get("sources", ())
        if not isinstance(sources, (list, tuple)) or not all(isinstance(s, str) for s in sources):
            raise ConfigError(f"{where}: 'sources' must be a list of strings")
        try:
            return cls(
                name=str(data["name"]),
                description=str(data.get("description", "")),
                cpu=str(data.get("cpu", "")),
                modes=modes,
                default_mode=str(data["default_mode"]),
                sources=tuple(sources),
            )
        except ValueError as e:
            raise ConfigError(f"{where}: {e}") from None

    @classmethod
    def load(cls, name_or_path: str | Path) -> DeviceProfile:
        """A shipped profile by name (:func:`available_devices`: ``jetson_nano``, ``odroid_xu4``) or a
        profile file by path. Raises :class:`alight.errors.ConfigError` for an unknown name or a bad
        file."""
        text, where = _read_profile(name_or_path)
        return cls.from_dict(load_yaml_text(text, where, "device profile", allow_empty=True), where)


def _read_profile(name_or_path: str | Path) -> tuple[str, str]:
    p = Path(name_or_path)
    if isinstance(name_or_path, Path) or p.suffix in (".yaml", ".yml") or len(p.parts) > 1:
        if not p.is_file():
            raise ConfigError(f"device profile file not found: {p}")
        return p.read_text(encoding="utf-8"), str(p)
    name = str(name_or_path)
    if name not in available_devices():
        raise ConfigError(f"unknown device {name!r}; shipped devices: {list(available_devices())}")
    res = resources.files("alight.energy").joinpath(_DEVICE_DIR, f"{name}.yaml")
    return res.read_text(encoding="utf-8"), f"alight/energy/{_DEVICE_DIR}/{name}.yaml"


def available_devices() -> tuple[str, ...]:
    """Names of the shipped device profiles."""
    d = resources.files("alight.energy").joinpath(_DEVICE_DIR)
    return tuple(sorted(p.name[: -len(".yaml")] for p in d.iterdir() if p.name.endswith(".yaml")))


def _as_profile(device: DeviceProfile | str) -> DeviceProfile:
    return device if isinstance(device, DeviceProfile) else DeviceProfile.load(device)


def device_cpu_s(
    cpu_s_host: float,
    device: DeviceProfile | str,
    mode: str | None = None,
    *,
    host_mips_1t: float = HOST_MIPS_1T,
) -> float:
    """CPU seconds on the device's core for ``cpu_s_host`` seconds on the host (module docstring, step 1)."""
    return float(cpu_s_host) * _as_profile(device).mode(mode).cpu_time_factor(host_mips_1t)


def compute_energy_J(
    cpu_s_host: float,
    device: DeviceProfile | str,
    mode: str | None = None,
    *,
    duration_s: float = 0.0,
    include_idle: bool = False,
    host_mips_1t: float = HOST_MIPS_1T,
) -> float:
    """Energy (J) the device spends on ``cpu_s_host`` host CPU seconds of work (module docstring):
    ``cpu_s_host * host_mips_1t / cpu_mips_1t * (active_W - idle_W) / cores``, plus ``idle_W *
    duration_s`` when ``include_idle`` (the whole board over a flight of ``duration_s`` seconds, as
    powprofiler's total-system model)."""
    cpu = float(cpu_s_host)
    if not (math.isfinite(cpu) and cpu >= 0):
        raise ValueError(f"cpu_s_host must be finite and >= 0, got {cpu_s_host}")
    if not (math.isfinite(duration_s) and duration_s >= 0):
        raise ValueError(f"duration_s must be finite and >= 0, got {duration_s}")
    m = _as_profile(device).mode(mode)
    energy = cpu * m.cpu_time_factor(host_mips_1t) * m.busy_core_W
    if include_idle:
        energy += m.idle_W * float(duration_s)
    return energy


def profile_summary(device: DeviceProfile | str, host_mips_1t: float = HOST_MIPS_1T) -> list[dict[str, Any]]:
    """One row per power mode: cores, clock, idle and active power, W per busy core, device seconds per
    host second (for reports)."""
    prof = _as_profile(device)
    return [
        {
            "device": prof.name,
            "mode": m.name,
            "cores": m.cores,
            "cpu_freq_MHz": m.cpu_freq_MHz,
            "idle_W": m.idle_W,
            "active_W": m.active_W,
            "busy_core_W": m.busy_core_W,
            "cpu_time_factor": m.cpu_time_factor(host_mips_1t),
        }
        for m in prof.modes.values()
    ]


__all__ = [
    "HOST_MIPS_1T",
    "DeviceProfile",
    "PowerMode",
    "available_devices",
    "compute_energy_J",
    "device_cpu_s",
    "profile_summary",
]
