"""Quality of service (QoS) of the landing-marker detector and its energy: paper 004's energy-sensitive
deployment (Zamanakos et al., Sec. III, with powprofiler, Seewald et al. 2019).

Paper 004, Sec. III-A: "the developer specifies the maximum and minimum QoS level for each algorithm",
powprofiler "iterate[s] through all possible combinations and empirically sample[s] the energy
consumption of each combination of QoS parameters", "builds a single model mapping QoS to total system
energy consumption. Coarse-grained sample is employed to reduce the number of experiments, and missing
values are automatically inferred from the others by the means of a multivariate linear interpolation",
and the mission runs "at the highest possible QoS level that does not exceed the available energy
budget". The paper keeps the levels static during a mission ("automatic adaptation during different
phases of the mission is ... considered future work"); :class:`PhasePolicy` is that future work.

What is here
------------
- :class:`QosSetting` ``(rate_hz, image_scale, max_kernel_px)``: detection rate (frames processed per
  second), the factor the image is resized by before detection (``cv2.resize``, ``INTER_AREA``) and the
  largest n-fold kernel size the adaptive search may try (paper 004's "kernel size", in pixels of the
  resized image). **Quality order** (explicit, used by every "highest quality" choice)::

      quality = (rate_hz / 30) * image_scale * (max_kernel_px / 41)

  the product of each parameter relative to the top of the shipped grid (30 Hz, full resolution, the
  n-fold detector's largest default kernel 41 px), so halving any one of them halves the quality. Ties
  (equal products, to 12 digits) are broken by rate, then scale, then kernel. Settings compare (``<``,
  ``max``, ``sorted``) by this order.
- :class:`QosMeasurements`: what the profiler (:mod:`alight.evaluation.qos_profile`) measured: host
  CPU seconds per frame on the (image_scale x max_kernel_px) grid for a mix of rendered frames,
  detection rates and the provenance (host, date, load). Stored as YAML (``models/sdu_qos.yaml`` is shipped).
- :class:`QosEnergyModel`: the powprofiler model. A grid of compute power (J/s) over (rate_hz,
  image_scale, max_kernel_px) and a multivariate linear interpolation
  (``scipy.interpolate.RegularGridInterpolator``, ``method="linear"``: exact at grid points, trilinear
  between them, an error outside the sampled box). Built from measurements on a device power profile
  (:mod:`alight.energy.compute`): ``P[r, s, k] = rate_r * t_host[s, k] * host/device speed ratio *
  W per busy core``; the rate axis is exact (energy is linear in the rate), the scale and kernel axes are
  measured. ``best_within_budget`` picks the highest-quality setting whose predicted energy fits.
- :class:`PhasePolicy`: a setting per mission mode (:class:`alight.types.Mode`); ``PhasePolicy.fixed``
  is the paper's static deployment; :data:`DEFAULT_PHASE_POLICY` is the phase rule of the README;
  :func:`budget_policy` chooses the per-phase settings that maximise a weighted log-quality utility
  under an energy budget (exact multiple-choice knapsack over the grid by Pareto fronts); its default
  weights keep the default rule's shape, scaled to the budget.
- ``alight.perception.qos_detector.QosDetector`` (a perception block; this package is a leaf):
  wraps a detector (``SduMarkerDetector`` or ``NFoldDetector``) to run it at a
  setting: frames are skipped to the rate, the image is resized, the kernel sizes are capped, and the
  pixels are mapped back to full resolution (so geolocation is unchanged). It counts the frames it
  processed per setting; a mission's compute energy is then ``model.mission_energy_J(counts)``:
  **deterministic** (energy per frame from the model, not from live timings, so a seed reproduces its
  result.json), like powprofiler, which measures once to build a model and then uses the model. The CPU
  time of each call is also measured (``cpu_s_measured``), for information only.
"""

from __future__ import annotations

import datetime as _dt
import functools
import itertools
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import NDArray
from scipy.interpolate import RegularGridInterpolator

from alight.energy.compute import DeviceProfile
from alight.errors import ConfigError
from alight.types import FloatArray, Mode
from alight.yaml_io import load_yaml_text

REFERENCE_RATE_HZ = 30.0
"""Rate at which the rate factor of :attr:`QosSetting.quality` is 1 (Hz)."""
REFERENCE_KERNEL_PX = 41
"""Kernel cap at which the kernel factor of :attr:`QosSetting.quality` is 1 (px): the n-fold detector's
largest default kernel size."""

MODEL_FORMAT = "alight-qos-measurements/1"
"""The ``format`` key of a measurements file."""

FRAME_KINDS = ("far", "near", "partial", "absent")
"""Frame categories of the profiler's mix: pad fully in view from high up / close, partly in view,
not in view."""

_MODEL_DIR = "models"


# --------------------------------------------------------------------------------------------------
# Settings
# --------------------------------------------------------------------------------------------------


@functools.total_ordering
@dataclass(frozen=True, slots=True, eq=True)
class QosSetting:
    """One quality-of-service level of the detector (module docstring for the quality order)."""

    rate_hz: float
    """Frames processed per second (Hz); frames in between are skipped."""
    image_scale: float
    """Resize factor of the image before detection, in (0, 1] (1: full resolution)."""
    max_kernel_px: int
    """Largest n-fold kernel size the adaptive search may try (px of the resized image); the sizes of
    the detector's list above it are dropped."""

    def __post_init__(self) -> None:
        r, s, k = self.rate_hz, self.image_scale, self.max_kernel_px
        if isinstance(r, bool) or not isinstance(r, (int, float)) or not (math.isfinite(r) and r > 0):
            raise ValueError(f"QosSetting.rate_hz must be a positive number, got {r!r}")
        if isinstance(s, bool) or not isinstance(s, (int, float)) or not (math.isfinite(s) and 0 < s <= 1):
            raise ValueError(f"QosSetting.image_scale must be in (0, 1], got {s!r}")
        if isinstance(k, bool) or int(k) != k or k < 5:
            raise ValueError(f"QosSetting.max_kernel_px must be an integer >= 5, got {k!r}")
        object.__setattr__(self, "rate_hz", float(r))
        object.__setattr__(self, "image_scale", float(s))
        object.__setattr__(self, "max_kernel_px", int(k))

    @property
    def quality(self) -> float:
        """``(rate_hz / 30) * image_scale * (max_kernel_px / 41)`` (module docstring)."""
        return (
            (self.rate_hz / REFERENCE_RATE_HZ) * self.image_scale * (self.max_kernel_px / REFERENCE_KERNEL_PX)
        )

    @property
    def rank(self) -> tuple[float, float, float, int]:
        """The sort key of the quality order: quality (12 digits), then rate, scale, kernel."""
        return (round(self.quality, 12), self.rate_hz, self.image_scale, self.max_kernel_px)

    def __lt__(self, other: object) -> bool:
        if not isinstance(other, QosSetting):
            return NotImplemented
        return self.rank < other.rank

    def as_tuple(self) -> tuple[float, float, int]:
        return (self.rate_hz, self.image_scale, self.max_kernel_px)

    def __str__(self) -> str:
        return f"{self.rate_hz:g} Hz, scale {self.image_scale:g}, kernel <= {self.max_kernel_px} px"


# --------------------------------------------------------------------------------------------------
# Measurements (the profiler's output file)
# --------------------------------------------------------------------------------------------------


def _grid_array(value: object, shape: tuple[int, int], what: str, where: str) -> NDArray[np.float64]:
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ConfigError(f"{where}: {what} is not a numeric table") from None
    if a.shape != shape:
        raise ConfigError(
            f"{where}: {what} must have shape {shape} (image_scale x max_kernel_px), got {a.shape}"
        )
    if not np.isfinite(a).all():
        raise ConfigError(f"{where}: {what} has non-finite entries")
    return a


def _axis(value: object, name: str, where: str) -> tuple[float, ...]:
    try:
        a = tuple(float(v) for v in value)  # type: ignore[attr-defined]
    except (TypeError, ValueError):
        raise ConfigError(f"{where}: axis {name} must be a list of numbers") from None
    if len(a) < 2 or not all(math.isfinite(v) for v in a) or any(b <= c for c, b in itertools.pairwise(a)):
        raise ConfigError(f"{where}: axis {name} must have >= 2 strictly increasing finite values, got {a}")
    return a


@dataclass(frozen=True)
class QosMeasurements:
    """What :mod:`alight.evaluation.qos_profile` measured (one file). Tables are indexed ``[image_scale,
    max_kernel_px]``; CPU times are host CPU seconds per processed frame."""

    rate_hz: tuple[float, ...]
    """Rate axis of the energy model (Hz): not measured (energy is linear in the rate)."""
    image_scale: tuple[float, ...]
    max_kernel_px: tuple[float, ...]
    cpu_s_per_frame: Mapping[str, NDArray[np.float64]]
    """Per frame kind (:data:`FRAME_KINDS`) and ``mix`` (all frames): mean over the frames of each frame's
    median CPU time over the repeats (s). The mean, because energy adds up over frames."""
    cpu_s_per_frame_median: Mapping[str, NDArray[np.float64]] = field(default_factory=dict)
    """Same, median over the frames instead of the mean (s), for reference."""
    detection_rate: Mapping[str, NDArray[np.float64]] = field(default_factory=dict)
    """Fraction of frames with the pad centre in view where the fused pixel is within tolerance of the
    truth, per kind (``far``, ``near``, ``partial``) and ``visible`` (all three)."""
    false_detection_rate: NDArray[np.float64] | None = None
    """Fraction of ``absent`` frames (no pad in view) with any detection."""
    host_mips_1t: float = 0.0
    """The measuring host's single-thread 7-Zip rating per CPU second (see :mod:`alight.energy.compute`)."""
    info: Mapping[str, Any] = field(default_factory=dict)
    """Provenance: detector, host, date, frames, load, notes."""

    @property
    def shape(self) -> tuple[int, int]:
        return (len(self.image_scale), len(self.max_kernel_px))

    @classmethod
    def from_dict(cls, data: object, where: str = "<dict>") -> QosMeasurements:
        if not isinstance(data, Mapping):
            raise ConfigError(f"{where}: a QoS measurements file must be a mapping")
        if data.get("format") != MODEL_FORMAT:
            raise ConfigError(f"{where}: format must be {MODEL_FORMAT!r}, got {data.get('format')!r}")
        axes = data.get("axes")
        if not isinstance(axes, Mapping) or set(axes) != {"rate_hz", "image_scale", "max_kernel_px"}:
            raise ConfigError(f"{where}: 'axes' must have exactly rate_hz, image_scale, max_kernel_px")
        rate = _axis(axes["rate_hz"], "rate_hz", where)
        scale = _axis(axes["image_scale"], "image_scale", where)
        kern = _axis(axes["max_kernel_px"], "max_kernel_px", where)
        if rate[0] <= 0 or scale[0] <= 0 or scale[-1] > 1 or kern[0] < 5:
            raise ConfigError(f"{where}: axes out of range (rate > 0, 0 < scale <= 1, kernel >= 5)")
        shape = (len(scale), len(kern))

        def tables(key: str, required: bool) -> dict[str, NDArray[np.float64]]:
            raw = data.get(key)
            if raw is None:
                if required:
                    raise ConfigError(f"{where}: missing {key!r}")
                return {}
            if not isinstance(raw, Mapping):
                raise ConfigError(f"{where}: {key!r} must map frame kinds to tables")
            return {str(k): _grid_array(v, shape, f"{key}.{k}", where) for k, v in raw.items()}

        cpu = tables("cpu_s_per_frame", True)
        if "mix" not in cpu:
            raise ConfigError(f"{where}: cpu_s_per_frame must have a 'mix' table")
        if any((a < 0).any() for a in cpu.values()):
            raise ConfigError(f"{where}: cpu_s_per_frame has negative entries")
        fdr = data.get("false_detection_rate")
        mips = data.get("host_mips_1t")
        if (
            isinstance(mips, bool)
            or not isinstance(mips, (int, float))
            or not (math.isfinite(mips) and mips > 0)
        ):
            raise ConfigError(f"{where}: host_mips_1t must be a positive number, got {mips!r}")
        return cls(
            rate_hz=rate,
            image_scale=scale,
            max_kernel_px=kern,
            cpu_s_per_frame=cpu,
            cpu_s_per_frame_median=tables("cpu_s_per_frame_median", False),
            detection_rate=tables("detection_rate", False),
            false_detection_rate=None
            if fdr is None
            else _grid_array(fdr, shape, "false_detection_rate", where),
            host_mips_1t=float(mips),
            info=dict(data.get("info") or {}),
        )

    def to_dict(self) -> dict[str, Any]:
        def t(m: Mapping[str, NDArray[np.float64]], digits: int) -> dict[str, list[list[float]]]:
            return {k: np.round(v, digits).tolist() for k, v in m.items()}

        out: dict[str, Any] = {
            "format": MODEL_FORMAT,
            "info": dict(self.info),
            "host_mips_1t": float(self.host_mips_1t),
            "axes": {
                "rate_hz": list(self.rate_hz),
                "image_scale": list(self.image_scale),
                "max_kernel_px": [int(k) if float(k).is_integer() else k for k in self.max_kernel_px],
            },
            "cpu_s_per_frame": t(self.cpu_s_per_frame, 7),
            "cpu_s_per_frame_median": t(self.cpu_s_per_frame_median, 7),
            "detection_rate": t(self.detection_rate, 4),
        }
        if self.false_detection_rate is not None:
            out["false_detection_rate"] = np.round(self.false_detection_rate, 4).tolist()
        return out

    @classmethod
    def load(cls, path: str | Path | None = None) -> QosMeasurements:
        """Read a measurements file (default: the shipped ``models/sdu_qos.yaml``)."""
        if path is None:
            res = resources.files("alight.energy").joinpath(_MODEL_DIR, "sdu_qos.yaml")
            text, where = res.read_text(encoding="utf-8"), f"alight/energy/{_MODEL_DIR}/sdu_qos.yaml"
        else:
            p = Path(path)
            if not p.is_file():
                raise ConfigError(f"QoS measurements file not found: {p}")
            text, where = p.read_text(encoding="utf-8"), str(p)
        return cls.from_dict(load_yaml_text(text, where, "QoS measurements file", allow_empty=True), where)

    def save(self, path: str | Path, header: str = "") -> None:
        """Write the file (YAML), with ``header`` as leading comment lines."""
        lines = "".join(f"# {ln}\n" if ln else "#\n" for ln in header.splitlines())
        body = yaml.safe_dump(self.to_dict(), sort_keys=False, default_flow_style=None, width=110)
        Path(path).write_text(lines + body, encoding="utf-8")


def shipped_model_path() -> Path:
    """Path of the shipped measurements file ``models/sdu_qos.yaml``."""
    return Path(str(resources.files("alight.energy").joinpath(_MODEL_DIR, "sdu_qos.yaml")))


# --------------------------------------------------------------------------------------------------
# The model
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class BudgetChoice:
    """Result of :meth:`QosEnergyModel.best_within_budget`."""

    setting: QosSetting | None
    """The highest-quality setting that fits; None when none does."""
    predicted_J: float | None
    """Its predicted energy over the duration (J)."""
    reason: str
    """Why this one (or why none)."""


class QosEnergyModel:
    """Compute power as a function of the QoS setting, by multivariate linear interpolation over a grid
    (module docstring).

    Parameters
    ----------
    rate_hz, image_scale, max_kernel_px:
        The grid axes, each >= 2 strictly increasing values.
    power_W:
        Compute power (J/s, the energy the detector adds per second of flight) at each grid point, shape
        ``(len(rate_hz), len(image_scale), len(max_kernel_px))``.
    baseline_W:
        Power added to every setting (W): the board's idle power when the model is of the total system
        energy (``include_idle``), else 0. Not part of the per-frame energy.
    busy_core_W:
        Power of one busy device core (W), when known: then ``utilisation(setting) = power / busy_core_W``
        is the fraction of one core the setting keeps busy.
    description:
        Free text (device, mode, source file).
    """

    def __init__(
        self,
        rate_hz: Sequence[float],
        image_scale: Sequence[float],
        max_kernel_px: Sequence[float],
        power_W: object,
        *,
        baseline_W: float = 0.0,
        busy_core_W: float | None = None,
        description: str = "",
    ) -> None:
        where = "QosEnergyModel"
        self.rate_hz = _axis(rate_hz, "rate_hz", where)
        self.image_scale = _axis(image_scale, "image_scale", where)
        self.max_kernel_px = _axis(max_kernel_px, "max_kernel_px", where)
        shape = (len(self.rate_hz), len(self.image_scale), len(self.max_kernel_px))
        P = np.array(power_W, dtype=np.float64)
        if P.shape != shape:
            raise ValueError(f"power_W must have shape {shape} (rate x scale x kernel), got {P.shape}")
        if not np.isfinite(P).all() or (P < 0).any():
            raise ValueError("power_W must be finite and >= 0")
        if not (math.isfinite(baseline_W) and baseline_W >= 0):
            raise ValueError(f"baseline_W must be finite and >= 0, got {baseline_W}")
        if busy_core_W is not None and not (math.isfinite(busy_core_W) and busy_core_W > 0):
            raise ValueError(f"busy_core_W must be positive, got {busy_core_W}")
        P.setflags(write=False)
        self.power_W = P
        self.baseline_W = float(baseline_W)
        self.busy_core_W = None if busy_core_W is None else float(busy_core_W)
        self.description = description
        self._interp = RegularGridInterpolator(
            (self.rate_hz, self.image_scale, self.max_kernel_px), P, method="linear", bounds_error=True
        )

    # -------------------------------------------------------------------------------- construction

    @classmethod
    def from_measurements(
        cls,
        meas: QosMeasurements,
        device: DeviceProfile | str = "jetson_nano",
        mode: str | None = None,
        *,
        frames: str = "mix",
        include_idle: bool = False,
    ) -> QosEnergyModel:
        """The model on a device: ``P[r, s, k] = rate_r * cpu_s_per_frame[frames][s, k] * host_mips /
        device_mips * busy_core_W`` (+ ``idle_W`` as baseline with ``include_idle``). ``frames``: which
        table of the measurements (``mix`` or one of :data:`FRAME_KINDS`)."""
        prof = device if isinstance(device, DeviceProfile) else DeviceProfile.load(device)
        m = prof.mode(mode)
        if frames not in meas.cpu_s_per_frame:
            raise ConfigError(
                f"no CPU-time table {frames!r} in the measurements; have {sorted(meas.cpu_s_per_frame)}"
            )
        t_dev = meas.cpu_s_per_frame[frames] * m.cpu_time_factor(meas.host_mips_1t)
        P = np.asarray(meas.rate_hz)[:, None, None] * t_dev[None, :, :] * m.busy_core_W
        src = meas.info.get("source", "measurements")
        return cls(
            meas.rate_hz,
            meas.image_scale,
            meas.max_kernel_px,
            P,
            baseline_W=m.idle_W if include_idle else 0.0,
            busy_core_W=m.busy_core_W,
            description=f"{prof.name} {m.name}, {frames} frames, from {src}"
            + (", total system (idle included)" if include_idle else ", compute only"),
        )

    @classmethod
    def load(
        cls,
        path: str | Path | None = None,
        *,
        device: DeviceProfile | str = "jetson_nano",
        mode: str | None = None,
        frames: str = "mix",
        include_idle: bool = False,
    ) -> QosEnergyModel:
        """:meth:`from_measurements` of a measurements file (default: the shipped ``sdu_qos.yaml``)."""
        return cls.from_measurements(
            QosMeasurements.load(path), device, mode, frames=frames, include_idle=include_idle
        )

    # -------------------------------------------------------------------------------- queries

    def grid_settings(self) -> list[QosSetting]:
        """Every grid point as a setting (the sampled QoS levels), lowest quality first."""
        return sorted(
            QosSetting(r, s, int(round(k)))
            for r, s, k in itertools.product(self.rate_hz, self.image_scale, self.max_kernel_px)
        )

    def _points(self, settings: Sequence[QosSetting]) -> FloatArray:
        pts = np.array([s.as_tuple() for s in settings], dtype=np.float64).reshape(-1, 3)
        names = ("rate_hz", "image_scale", "max_kernel_px")
        axes = (self.rate_hz, self.image_scale, self.max_kernel_px)
        for j, (name, ax) in enumerate(zip(names, axes, strict=True)):
            bad = (pts[:, j] < ax[0] - 1e-12) | (pts[:, j] > ax[-1] + 1e-12)
            if bad.any():
                s = settings[int(np.argmax(bad))]
                raise ValueError(
                    f"QoS setting ({s}) is outside the sampled range: {name} must be in "
                    f"[{ax[0]:g}, {ax[-1]:g}] (the model only interpolates, it does not extrapolate)"
                )
            pts[:, j] = np.clip(pts[:, j], ax[0], ax[-1])
        return pts

    def power_W_many(self, settings: Sequence[QosSetting]) -> FloatArray:
        """Interpolated compute power (W) of each setting, without the baseline, shape (N,)."""
        if len(settings) == 0:
            return np.zeros(0)
        return np.asarray(self._interp(self._points(settings)), dtype=np.float64)

    def energy_per_s(self, setting: QosSetting) -> float:
        """Predicted energy per second of flight at ``setting`` (W = J/s): the baseline plus the
        interpolated compute power. Exact at grid points, multilinear between; ValueError outside."""
        return self.baseline_W + float(self.power_W_many([setting])[0])

    def energy_per_frame_J(self, setting: QosSetting) -> float:
        """Energy of one processed frame at ``setting`` (J): compute power / rate (no baseline)."""
        return float(self.power_W_many([setting])[0]) / setting.rate_hz

    def utilisation(self, setting: QosSetting) -> float | None:
        """Fraction of one device core the setting keeps busy (None when the model has no core power);
        above 1 the device cannot keep up in real time."""
        if self.busy_core_W is None:
            return None
        return float(self.power_W_many([setting])[0]) / self.busy_core_W

    def predict_J(self, setting: QosSetting, duration_s: float) -> float:
        """Predicted energy (J) over ``duration_s`` seconds at ``setting``."""
        if not (math.isfinite(duration_s) and duration_s >= 0):
            raise ValueError(f"duration_s must be finite and >= 0, got {duration_s}")
        return self.energy_per_s(setting) * duration_s

    def mission_energy_J(self, frames_by_setting: Mapping[QosSetting, int], duration_s: float = 0.0) -> float:
        """Compute energy of a mission (J): the sum over settings of frames processed x energy per frame
        at that setting, plus ``baseline_W * duration_s``. Deterministic (module docstring)."""
        if not (math.isfinite(duration_s) and duration_s >= 0):
            raise ValueError(f"duration_s must be finite and >= 0, got {duration_s}")
        total = self.baseline_W * duration_s
        for s, n in frames_by_setting.items():
            if n < 0:
                raise ValueError(f"negative frame count {n} for {s}")
            if n:
                total += n * self.energy_per_frame_J(s)
        return total

    def best_within_budget(
        self,
        budget_J: float,
        duration_s: float,
        candidates: Iterable[QosSetting] | None = None,
        *,
        max_utilisation: float | None = 1.0,
    ) -> BudgetChoice:
        """The highest-quality setting (quality order of the module docstring) whose predicted energy
        over ``duration_s`` is at most ``budget_J``; candidates default to the grid points. With
        ``max_utilisation`` (and a model that knows its core power) settings that need more than that
        fraction of one device core are left out (they cannot run in real time). Returns a
        :class:`BudgetChoice`; its ``setting`` is None, with the reason, when nothing fits."""
        if not (math.isfinite(budget_J) and math.isfinite(duration_s) and duration_s > 0):
            raise ValueError(f"budget_J must be finite and duration_s > 0, got {budget_J}, {duration_s}")
        cands = self.grid_settings() if candidates is None else sorted(candidates)
        if not cands:
            raise ValueError("no candidate settings")
        power = self.power_W_many(cands)
        energy = (self.baseline_W + power) * duration_s
        ok = energy <= budget_J * (1 + 1e-12)
        util_dropped = 0
        if max_utilisation is not None and self.busy_core_W is not None:
            fast = power / self.busy_core_W <= max_utilisation
            util_dropped = int(np.sum(ok & ~fast))
            ok &= fast
        if not ok.any():
            i = int(np.argmin(energy))
            why = (
                f"no setting fits {budget_J:.4g} J over {duration_s:g} s: the cheapest, {cands[i]}, "
                f"needs {energy[i]:.4g} J"
            )
            if self.baseline_W > 0 and self.baseline_W * duration_s > budget_J:
                why += f" (the idle baseline alone is {self.baseline_W * duration_s:.4g} J)"
            if util_dropped:
                why += f"; {util_dropped} setting(s) within budget were left out as slower than real time"
            return BudgetChoice(None, None, why)
        i = int(max(np.flatnonzero(ok), key=lambda j: cands[j].rank))
        why = (
            f"highest quality ({cands[i].quality:.3g}) of {int(ok.sum())}/{len(cands)} settings within "
            f"{budget_J:.4g} J over {duration_s:g} s"
        )
        return BudgetChoice(cands[i], float(energy[i]), why)


# --------------------------------------------------------------------------------------------------
# Phase policies
# --------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class PhasePolicy:
    """A QoS setting per mission mode; modes without an entry use ``default``.

    ``oblique``: settings for modes where the camera looks at the ground obliquely, the vehicle tilted by
    more than ``oblique_tilt_rad`` (held against a strong wind): the pad then appears smaller and
    foreshortened, and the n-fold detector finds it in fewer frames (EXPLORE_SETTING's docstring has
    the measurements), so those modes spend more per frame only while the view is hard."""

    settings: Mapping[Mode, QosSetting]
    default: QosSetting
    oblique: Mapping[Mode, QosSetting] = field(default_factory=dict)
    oblique_tilt_rad: float = math.radians(20.0)

    def __post_init__(self) -> None:
        def clean(settings: Mapping[Mode, QosSetting], what: str) -> dict[Mode, QosSetting]:
            out: dict[Mode, QosSetting] = {}
            for k, v in dict(settings).items():
                mode = Mode(k)
                if not isinstance(v, QosSetting):
                    raise ValueError(
                        f"PhasePolicy: the {what}setting of {mode} must be a QosSetting, got {v!r}"
                    )
                out[mode] = v
            return out

        object.__setattr__(self, "settings", clean(self.settings, ""))
        object.__setattr__(self, "oblique", clean(self.oblique, "oblique "))
        if not isinstance(self.default, QosSetting):
            raise ValueError(f"PhasePolicy.default must be a QosSetting, got {self.default!r}")
        if not (0.0 < self.oblique_tilt_rad < math.pi / 2):
            raise ValueError(
                f"PhasePolicy.oblique_tilt_rad must be in (0, pi/2), got {self.oblique_tilt_rad}"
            )

    def setting_for(self, mode: Mode | str, oblique: bool = False) -> QosSetting:
        """The setting to use in ``mode``; ``oblique``: the camera is tilted past ``oblique_tilt_rad``."""
        m = Mode(mode)
        if oblique and m in self.oblique:
            return self.oblique[m]
        return self.settings.get(m, self.default)

    def __getitem__(self, mode: Mode | str) -> QosSetting:
        return self.setting_for(mode)

    def all_settings(self) -> list[QosSetting]:
        """Every distinct setting the policy can select, lowest quality first."""
        return sorted(set(self.settings.values()) | set(self.oblique.values()) | {self.default})

    @classmethod
    def fixed(cls, setting: QosSetting) -> PhasePolicy:
        """One setting in every mode (paper 004's static QoS levels)."""
        return cls({}, setting)

    def predict_J(self, model: QosEnergyModel, phase_durations: Mapping[Mode | str, float]) -> float:
        """Predicted energy (J) of a mission spending ``phase_durations[mode]`` seconds in each mode."""
        return sum(model.predict_J(self.setting_for(m), float(d)) for m, d in phase_durations.items())


EXPLORE_SETTING = QosSetting(5.0, 0.5, 21)
"""Exploration: the pad is searched for from 12 m, where the 1.5 m pad spans ~50-60 px of the default
752 px, 90 deg camera and the n-fold disc ~30 px; at scale 0.5 the disc is still ~15 px wide, found with
the kernels 13-21 px (measured: every ``far`` frame, 6-12 m, detected at scale 0.5 with the cap 21; the
cap 13 missed a quarter). Most exploration frames show no pad, where the cap matters most (the search
tries every allowed size). The footprint at 12 m is ~14 m x 23 m, so even at a relative speed of 8 m/s
(4 m/s cruise against a 4 m/s platform) the pad stays in view ~2 s: 5 Hz gives it ~9 chances.

That holds for a level camera. Seen obliquely the pad is found far less often: rendered frames from 12 m
with the pad anywhere in view, 40 per tilt (``benchmarks/oblique_detection.py``), found in 0.90 of the
level frames at this setting but 0.33 at 30 deg and 0.20 at 35 deg. A vehicle holding its position in
paper 004's 12 m/s gusts tilts 30-40 deg; :data:`OBLIQUE_SEARCH_SETTING` is for then."""
TRACK_SETTING = QosSetting(20.0, 0.5, 29)
"""Tracking: the pad is a few metres below (track height 2.5 m) and spans 200+ px; at scale 0.5 every
``near`` and ``partial`` frame was detected (as at full scale), so the quality goes into the rate, which
the estimator needs to follow a turning platform (paper 000 found 20 Hz sufficient; paper 004's filter
predicts between frames), and a kernel cap of 29 px keeps margin for a partly occluded tip (paper 004,
Fig. 2: occlusion raises the kernel size the adaptive search needs)."""
LAND_SETTING = QosSetting(30.0, 1.0, 21)
"""Landing: every frame (30 Hz or the camera's rate: least latency where a miss costs most), full
resolution (the ArUco landmarks carry the fix when the n-fold tip leaves the view at the last metre; the
landing lasts seconds, so the budget barely notices), and small kernels (13-21 px): the marker is large
and the n-fold pattern is scale-free at its tip, so a small kernel finds it."""

OBLIQUE_SEARCH_SETTING = QosSetting(20.0, 1.0, 41)
"""Searching with the camera tilted past 20 deg (take-off and exploration in a strong wind): full
resolution and the whole kernel search at 20 Hz. At 35 deg of tilt from 12 m the pad is found in 0.72 of
the frames this way against 0.20 at EXPLORE_SETTING's half scale; the rate doubles the chances again
while the pad crosses the footprint (README.md has the closed-loop numbers). It costs ~4x
EXPLORE_SETTING per second, and only while the vehicle leans into the wind."""

DEFAULT_PHASE_POLICY = PhasePolicy(
    {
        Mode.IDLE: EXPLORE_SETTING,
        Mode.TAKEOFF: EXPLORE_SETTING,
        Mode.EXPLORE: EXPLORE_SETTING,
        Mode.TRACK: TRACK_SETTING,
        Mode.GO_AROUND: TRACK_SETTING,
        Mode.LAND: LAND_SETTING,
        Mode.LANDED: EXPLORE_SETTING,
        Mode.ABORT: EXPLORE_SETTING,
    },
    EXPLORE_SETTING,
    oblique={Mode.TAKEOFF: OBLIQUE_SEARCH_SETTING, Mode.EXPLORE: OBLIQUE_SEARCH_SETTING},
)
"""The default per-phase rule (the settings' docstrings say why; README.md has the measured numbers)."""


@dataclass(frozen=True, slots=True)
class BudgetPolicy:
    """Result of :func:`budget_policy`."""

    policy: PhasePolicy | None
    """The chosen per-phase settings; None when even the cheapest choice exceeds the budget."""
    predicted_J: float | None
    """Predicted energy of the mission with it (J)."""
    reason: str


def budget_policy(
    model: QosEnergyModel,
    budget_J: float,
    phase_durations: Mapping[Mode | str, float],
    candidates: Iterable[QosSetting] | None = None,
    *,
    weights: Mapping[Mode | str, float] | None = None,
    max_utilisation: float | None = 1.0,
) -> BudgetPolicy:
    """Per-phase settings that maximise the utility ``U = sum_p w_p d_p ln quality(s_p)`` subject to
    ``sum_p d_p energy_per_s(s_p) <= budget_J`` (``d_p`` the phase's expected duration in s, ``w_p`` its
    weight).

    Why a logarithm: with a linear utility (``sum w_p d_p quality``) the whole budget goes to whichever
    phase buys quality cheapest, and landing could end at the lowest level while exploring at the top.
    The logarithm gives diminishing returns, so at the optimum ``w_p / quality_p`` equals the price of
    quality times the same multiplier in every phase: each phase's quality is proportional to its
    weight, whatever the phase durations. The default weights are the qualities of
    :data:`DEFAULT_PHASE_POLICY`, so the result keeps the default rule's shape (landing > tracking >
    exploration), scaled up or down to the budget; equal weights give the same quality everywhere.

    Exact: a multiple-choice knapsack solved by merging per-phase Pareto fronts (energy, utility), each
    pruned of dominated partial choices, so the cost grows with the front size, not with
    ``len(candidates) ** phases``. Ties in utility go to the lower energy. Modes not in
    ``phase_durations`` get the cheapest candidate (the policy's default). Candidates default to the grid
    points; with ``max_utilisation`` settings slower than real time are left out (see
    :meth:`QosEnergyModel.best_within_budget`)."""
    if not (math.isfinite(budget_J)):
        raise ValueError(f"budget_J must be finite, got {budget_J}")
    real_time = _real_time_candidates(model, candidates, max_utilisation)
    if real_time is None:
        return BudgetPolicy(
            None, None, "every candidate needs more than one device core (slower than real time)"
        )
    cands, power = real_time
    rate = model.baseline_W + power
    cheapest = cands[int(np.argmin(rate))]
    phases = [Mode(m) for m in phase_durations]
    durs = [float(phase_durations[m]) for m in phase_durations]
    if any(not (math.isfinite(d) and d >= 0) for d in durs):
        raise ValueError(f"phase durations must be finite and >= 0, got {durs}")
    if weights is None:
        w = {p: DEFAULT_PHASE_POLICY[p].quality for p in phases}
    else:
        w = {Mode(k): float(v) for k, v in weights.items()}
        if any(not (math.isfinite(v) and v > 0) for v in w.values()):
            raise ValueError(f"weights must be positive, got {weights}")
    quality = np.log(np.array([c.quality for c in cands]))
    front = _pareto_front(rate, quality, phases, durs, w, budget_J)
    if front is None:
        e_min = sum(float(rate.min()) * dd for dd in durs)
        return BudgetPolicy(
            None,
            None,
            f"no per-phase choice fits {budget_J:.4g} J: the cheapest setting in every phase "
            f"needs {e_min:.4g} J",
        )
    e, v, ch = max(front, key=lambda m: (m[1], -m[0]))
    policy = PhasePolicy({p: cands[i] for p, i in zip(phases, ch, strict=True)}, cheapest)
    return BudgetPolicy(
        policy,
        float(e),
        f"maximal utility {v:.4g} (sum w d ln q) over {len(phases)} phase(s) within {budget_J:.4g} J "
        f"(predicted {e:.4g} J)",
    )


def _real_time_candidates(
    model: QosEnergyModel, candidates: Iterable[QosSetting] | None, max_utilisation: float | None
) -> tuple[list[QosSetting], FloatArray] | None:
    """:func:`budget_policy`'s candidates (sorted, distinct) and their power (W); with ``max_utilisation``
    only those within it of one busy core; None when that leaves none."""
    cands = model.grid_settings() if candidates is None else sorted(set(candidates))
    if not cands:
        raise ValueError("no candidate settings")
    power = model.power_W_many(cands)
    if max_utilisation is not None and model.busy_core_W is not None:
        keep = power / model.busy_core_W <= max_utilisation
        if not keep.any():
            return None
        cands = [c for c, k in zip(cands, keep, strict=True) if k]
        power = power[keep]
    return cands, power


def _pareto_front(
    rate: FloatArray,
    quality: FloatArray,
    phases: list[Mode],
    durs: list[float],
    w: Mapping[Mode, float],
    budget_J: float,
) -> list[tuple[float, float, tuple[int, ...]]] | None:
    """The non-dominated partial choices (energy J, utility, a candidate index per phase) of the
    multiple-choice knapsack, merged phase by phase; None when no choice fits ``budget_J``."""
    front: list[tuple[float, float, tuple[int, ...]]] = [(0.0, 0.0, ())]
    for p, d in zip(phases, durs, strict=True):
        e_opt = rate * d
        v_opt = quality * d * w.get(p, 1.0)  # ln quality: the utility of budget_policy's docstring
        merged = [(e + e_opt[i], v + v_opt[i], ch + (i,)) for e, v, ch in front for i in range(len(rate))]
        merged = [m for m in merged if m[0] <= budget_J * (1 + 1e-12)]
        if not merged:
            return None
        # keep the non-dominated ones: by energy ascending, value strictly increasing
        merged.sort(key=lambda m: (m[0], -m[1]))
        front = []
        best_v = -math.inf
        for m in merged:
            if m[1] > best_v + 1e-15:
                front.append(m)
                best_v = m[1]
    return front


def measurements_info(**extra: Any) -> dict[str, Any]:
    """A provenance mapping with the UTC date (for :class:`QosMeasurements.info`)."""
    return {"created_utc": _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ"), **extra}


__all__ = [
    "DEFAULT_PHASE_POLICY",
    "EXPLORE_SETTING",
    "OBLIQUE_SEARCH_SETTING",
    "FRAME_KINDS",
    "LAND_SETTING",
    "REFERENCE_KERNEL_PX",
    "REFERENCE_RATE_HZ",
    "TRACK_SETTING",
    "BudgetChoice",
    "BudgetPolicy",
    "PhasePolicy",
    "QosEnergyModel",
    "QosMeasurements",
    "QosSetting",
    "budget_policy",
    "shipped_model_path",
]
