"""The QoS profiler: powprofiler's sampling step (paper 004, Sec. III-A) for the SDU landing-marker detector.

For every (image_scale, max_kernel_px) pair of a coarse grid it measures the host CPU time per frame of
:class:`alight.perception.sdu_marker.SduMarkerDetector` run through
:class:`alight.perception.qos_detector.QosDetector`
(resize, capped adaptive kernel search, ArUco, fusion, mapping back), on frames rendered with alight's
:class:`~alight.sim.render.Renderer` through the default downward camera (752 x 480, 90 deg) over grass,
asphalt and concrete, with sensor noise. The frame mix has four kinds (:data:`~alight.energy.qos.FRAME_KINDS`,
equal numbers of each):

- ``far``: the pad fully in view from 6-12 m (exploration / early tracking altitude);
- ``near``: the pad fully in view from 2-6 m (tracking, landing);
- ``partial``: the pad centre in view from 1.5-4 m but not all of the pad (landing, a platform turning);
- ``absent``: no pad in view, 4-12 m up (exploration) - the costliest frames, where the adaptive search
  tries every allowed kernel size.

Each frame is timed ``repeats`` times at every setting (settings interleaved frame by frame so that the
load of a shared machine drifts over all of them alike), with ``time.process_time`` and OpenCV on one
thread; a frame's cost is the median of its repeats, and a setting's cost per frame is the **mean** over
the frames of a kind (energy adds up over frames; the median over frames is stored too). The detection
rate of each setting is recorded on the frames with the pad centre in view (the fused pixel within
``max(3 px, 5 % of the pad's side in pixels)`` of the projected pad centre) and the false-detection rate
on the ``absent`` frames.

The rate axis is not measured: compute energy per second is exactly the rate times the energy per frame.
The numbers are host-specific; :class:`alight.energy.qos.QosEnergyModel` turns them into device energy
with a device profile (:mod:`alight.energy.compute`), using the host's single-thread 7-Zip rating stored
in the file (measured with ``7z b -mmt1`` when 7-Zip is installed, else given with ``--host-mips``).

Run: ``python -m alight.evaluation.qos_profile --out src/alight/energy/models/sdu_qos.yaml`` (about a minute;
``--quick`` for a seconds-long smoke run).
"""

from __future__ import annotations

import argparse
import math
import os
import platform
import re
import shutil
import statistics
import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import cv2
import numpy as np

from alight.cameras import CameraMount, PinholeCamera, camera_pose_W
from alight.energy.compute import HOST_MIPS_1T
from alight.energy.qos import FRAME_KINDS, QosMeasurements, QosSetting, measurements_info
from alight.pads.sdu_pad import SduPad
from alight.perception.qos_detector import QosDetector
from alight.perception.sdu_marker import SduMarkerDetector
from alight.sim.render import Renderer, RenderOptions
from alight.sim.textures import make_ground_texture
from alight.types import FloatArray, Observation, rot_z

_ALTITUDES = {"far": (6.0, 12.0), "near": (2.0, 6.0), "partial": (1.5, 4.0), "absent": (4.0, 12.0)}
_DECK_Z = 0.5


@dataclass(frozen=True)
class ProfileConfig:
    """What the profiler samples."""

    rate_hz: tuple[float, ...] = (5.0, 10.0, 20.0, 30.0)
    """Rate axis of the model (Hz; not measured)."""
    image_scale: tuple[float, ...] = (0.5, 0.75, 1.0)
    max_kernel_px: tuple[int, ...] = (13, 21, 29, 41)
    """Kernel caps: sizes of the n-fold detector's default list 13, 17, ..., 41 (a cap between two sizes
    behaves as the smaller one); 13 is paper 004's fixed 13 x 13 kernel (no adaptation), 41 the whole
    adaptive search."""
    frames_per_kind: int = 16
    repeats: int = 5
    seed: int = 0
    grounds: tuple[str, ...] = ("grass", "asphalt", "concrete")
    noise_sigma_dn: float = 2.0
    max_tilt_rad: float = 0.2

    @classmethod
    def quick(cls) -> ProfileConfig:
        """A seconds-long run for tests: 2 x 2 grid, one frame of each kind, one repeat, one ground."""
        return cls(
            image_scale=(0.5, 1.0), max_kernel_px=(21, 41), frames_per_kind=1, repeats=1, grounds=("grass",)
        )


@dataclass
class Frame:
    kind: str
    image: np.ndarray
    center_px: FloatArray | None
    """Projected pad centre (px), None for ``absent`` frames."""
    pad_side_px: float


@dataclass
class _Acc:
    cpu: dict[tuple[int, int], list[float]] = field(default_factory=dict)
    hit: dict[tuple[int, int], list[bool]] = field(default_factory=dict)


def _tilt(rng: np.random.Generator, max_tilt: float) -> FloatArray:
    r, p, y = (
        rng.uniform(-max_tilt, max_tilt),
        rng.uniform(-max_tilt, max_tilt),
        rng.uniform(-math.pi, math.pi),
    )
    cr, sr, cp, sp = math.cos(r), math.sin(r), math.cos(p), math.sin(p)
    Rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]], dtype=np.float64)
    Ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]], dtype=np.float64)
    return rot_z(y) @ Ry @ Rx


def render_frames(cfg: ProfileConfig, rng: np.random.Generator) -> list[Frame]:
    """The frame mix (module docstring): ``frames_per_kind`` of each kind, grounds in turn."""
    cam = PinholeCamera.default_downward()
    mount = CameraMount.downward()
    pad = SduPad.default()
    opt = RenderOptions(noise_sigma_dn=cfg.noise_sigma_dn)
    renderers = [Renderer(cam, make_ground_texture(g, rng, size_px=512), pad, opt, rng) for g in cfg.grounds]
    corners_P = pad.quad_corners_P()
    W, H = cam.width, cam.height
    frames: list[Frame] = []
    n = 0
    for kind in FRAME_KINDS:
        lo, hi = _ALTITUDES[kind]
        done = tries = 0
        while done < cfg.frames_per_kind:
            tries += 1
            if tries > 2000:
                raise RuntimeError(f"could not place a {kind!r} frame")
            h = rng.uniform(lo, hi)
            R_WB = _tilt(rng, cfg.max_tilt_rad)
            yaw_P = rng.uniform(-math.pi, math.pi)
            if kind == "absent":
                far = rng.uniform(3.0, 6.0) * h + 10.0
                ang = rng.uniform(-math.pi, math.pi)
                p_WB = np.array([far * math.cos(ang), far * math.sin(ang), h + _DECK_Z])
            else:
                spread = 0.6 if kind == "partial" else 0.35
                p_WB = np.array(
                    [rng.uniform(-spread, spread) * h, rng.uniform(-spread, spread) * h, h + _DECK_Z]
                )
            p_WP = np.array([0.0, 0.0, _DECK_Z])
            p_WC, R_WC = camera_pose_W(p_WB, R_WB, mount)
            R_WP = rot_z(yaw_P)
            pts_C = (R_WC.T @ ((R_WP @ np.vstack([np.zeros(3), corners_P]).T).T + p_WP - p_WC).T).T
            px = cam.project(pts_C)
            inside = np.isfinite(px).all(axis=1) & (px[:, 0] > 2) & (px[:, 1] > 2)
            inside &= (px[:, 0] < W - 3) & (px[:, 1] < H - 3)
            if kind in ("far", "near") and not inside.all():
                continue
            if kind == "partial" and not (inside[0] and not inside[1:].all()):
                continue
            if (
                kind == "absent"
                and (
                    np.isfinite(px).all(axis=1)
                    & (np.abs(px[:, 0] - W / 2) < W)
                    & (np.abs(px[:, 1] - H / 2) < H)
                ).any()
            ):
                continue
            img = renderers[n % len(renderers)].render(p_WC, R_WC, (p_WP, yaw_P))
            n += 1
            done += 1
            z = float(pts_C[0, 2])
            side = float(cam.K[0, 0]) * pad.size_m / max(z, 1e-6)
            frames.append(Frame(kind, img, None if kind == "absent" else px[0].copy(), side))
    return frames


def measure_host_mips(timeout_s: float = 300.0) -> float | None:
    """The host's single-thread 7-Zip rating per CPU second (``7z b -mmt1``, the ``Tot:`` line's R/U
    column), or None when 7-Zip is not installed or the output is not understood."""
    exe = shutil.which("7z") or shutil.which("7zz") or shutil.which("7za")
    if exe is None:
        return None
    try:
        out = subprocess.run(
            [exe, "b", "-mmt1"], capture_output=True, text=True, timeout=timeout_s, check=False
        )
    except (OSError, subprocess.SubprocessError):
        return None
    m = re.search(r"^Tot:\s+\d+\s+(\d+)\s+\d+", out.stdout, re.MULTILINE)
    return float(m.group(1)) if m else None


def _host_info() -> dict[str, Any]:
    model = platform.processor() or ""
    try:
        with open("/proc/cpuinfo", encoding="utf-8") as f:
            for line in f:
                if line.startswith("model name"):
                    model = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    import numba
    import scipy

    return {
        "cpu": model,
        "machine": platform.machine(),
        "logical_cpus": os.cpu_count(),
        "system": f"{platform.system()} {platform.release()}",
        "python": platform.python_version(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "opencv": cv2.__version__,
        "numba": numba.__version__,
    }


_Pair = tuple[int, int]
"""A setting of the grid: (index into ``image_scale``, index into ``max_kernel_px``)."""


def _time_detectors(
    cfg: ProfileConfig, frames: list[Frame], rng: np.random.Generator, pairs: list[_Pair]
) -> dict[str, _Acc]:
    """Each frame's median CPU time and hit at every setting, by frame kind; the settings in a fresh
    random order on every frame (``rng``), single-threaded OpenCV, after a warm-up on the first frames."""
    inner = SduMarkerDetector(SduPad.default(), camera=PinholeCamera.default_downward())
    dets = {
        (i, j): QosDetector(
            inner, QosSetting(cfg.rate_hz[-1], cfg.image_scale[i], cfg.max_kernel_px[j]), throttle=False
        )
        for i, j in pairs
    }
    threads = cv2.getNumThreads()
    cv2.setNumThreads(1)
    acc = {kind: _Acc() for kind in FRAME_KINDS}
    try:
        for f in frames[: min(len(frames), 4)]:  # warm-up: numba caches, OpenCV buffers
            for d in dets.values():
                d.detect(f.image, 0.0)
        order = list(pairs)
        for n, f in enumerate(frames):
            rng.shuffle(order)
            a = acc[f.kind]
            for key in order:
                d = dets[key]
                times = []
                obs: list[Observation] = []
                for _ in range(cfg.repeats):
                    obs = d.detect(f.image, float(n))
                    times.append(d.last_cpu_s)
                a.cpu.setdefault(key, []).append(statistics.median(times))
                if f.center_px is None:
                    a.hit.setdefault(key, []).append(bool(obs))
                else:
                    tol = max(3.0, 0.05 * f.pad_side_px)
                    ok = bool(obs) and float(np.hypot(*(obs[0].pixels[0] - f.center_px))) <= tol
                    a.hit.setdefault(key, []).append(ok)
    finally:
        cv2.setNumThreads(threads)
    return acc


_Tables = dict[str, np.ndarray]


def _tables(
    cfg: ProfileConfig, acc: dict[str, _Acc], pairs: list[_Pair]
) -> tuple[_Tables, _Tables, _Tables, np.ndarray]:
    """The per-setting tables: CPU time's mean and median by kind and over the mix, the detection rate
    by kind and over the visible kinds, and the false detection rate on the frames without the pad."""
    shape = (len(cfg.image_scale), len(cfg.max_kernel_px))

    def table(values: dict[_Pair, list[float]] | None, fn: Any) -> np.ndarray:
        t = np.zeros(shape)
        for key in pairs:
            t[key] = fn(values[key]) if values and values.get(key) else 0.0
        return t

    mean = lambda v: float(np.mean(v))  # noqa: E731
    med = lambda v: float(np.median(v))  # noqa: E731
    cpu_mean = {k: table(acc[k].cpu, mean) for k in FRAME_KINDS}
    cpu_med = {k: table(acc[k].cpu, med) for k in FRAME_KINDS}
    all_cpu = {key: sum((acc[k].cpu[key] for k in FRAME_KINDS), []) for key in pairs}
    cpu_mean["mix"] = table(all_cpu, mean)
    cpu_med["mix"] = table(all_cpu, med)
    det = {
        k: table({key: [float(x) for x in acc[k].hit[key]] for key in pairs}, mean)
        for k in ("far", "near", "partial")
    }
    vis = {key: [float(x) for k in ("far", "near", "partial") for x in acc[k].hit[key]] for key in pairs}
    det["visible"] = table(vis, mean)
    fdr = table({key: [float(x) for x in acc["absent"].hit[key]] for key in pairs}, mean)
    return cpu_mean, cpu_med, det, fdr


def _profile_info(
    cfg: ProfileConfig,
    host_mips_1t: float | None,
    load0: tuple[float, float, float] | None,
    wall0: float,
) -> tuple[float, dict[str, Any]]:
    """The host's 7-Zip rating (given, measured or assumed) and the measurements' provenance."""
    mips_measured = measure_host_mips() if host_mips_1t is None else None
    mips = host_mips_1t if host_mips_1t is not None else (mips_measured or HOST_MIPS_1T)
    mips_how = (
        "given"
        if host_mips_1t is not None
        else ("measured: 7z b -mmt1" if mips_measured else "assumed: reference host")
    )
    load1 = os.getloadavg() if hasattr(os, "getloadavg") else None
    info = measurements_info(
        source="alight.evaluation.qos_profile",
        detector="SduMarkerDetector(SduPad.default(1.5 m), camera=default_downward) through QosDetector",
        camera="PinholeCamera.default_downward(): 752 x 480 px, f = 400 px, 90.7 deg horizontal",
        timer="time.process_time, cv2.setNumThreads(1)",
        statistic="per frame: median over repeats; per setting: mean (and median) over the frames of a kind",
        frames={
            "per_kind": cfg.frames_per_kind,
            "kinds": {k: f"{_ALTITUDES[k][0]:g}-{_ALTITUDES[k][1]:g} m" for k in FRAME_KINDS},
            "repeats": cfg.repeats,
            "grounds": list(cfg.grounds),
            "noise_sigma_dn": cfg.noise_sigma_dn,
            "seed": cfg.seed,
        },
        host=_host_info(),
        host_mips_1t_source=mips_how,
        load_average_1_5_15=None
        if load0 is None
        else {"start": [round(x, 2) for x in load0], "end": [round(x, 2) for x in (load1 or ())]},
        wall_time_s=round(time.perf_counter() - wall0, 1),
        note=(
            "host-specific CPU times; QosEnergyModel scales them to a device with a device profile. "
            "The machine is shared: process CPU time is robust to other processes' CPU use but not to "
            "their cache and memory contention"
        ),
    )
    return float(mips), info


def run_profile(
    cfg: ProfileConfig | None = None, *, host_mips_1t: float | None = None, frames: list[Frame] | None = None
) -> QosMeasurements:
    """Render the frame mix, time the detector at every (scale, kernel) pair and return the measurements
    (module docstring). ``host_mips_1t``: the host's 7-Zip rating (default: measured with 7-Zip when it
    is installed, else :data:`alight.energy.compute.HOST_MIPS_1T`, which is right only on the reference
    host). ``frames``: use these instead of rendering the mix of ``cfg`` (every kind must be present)."""
    cfg = cfg or ProfileConfig()
    wall0 = time.perf_counter()
    load0 = os.getloadavg() if hasattr(os, "getloadavg") else None
    rng = np.random.default_rng(cfg.seed)
    if frames is None:
        frames = render_frames(cfg, rng)
    elif {f.kind for f in frames} != set(FRAME_KINDS):
        raise ValueError(f"frames must include every kind {FRAME_KINDS}")
    pairs = [(i, j) for i in range(len(cfg.image_scale)) for j in range(len(cfg.max_kernel_px))]
    acc = _time_detectors(cfg, frames, rng, pairs)
    cpu_mean, cpu_med, det, fdr = _tables(cfg, acc, pairs)
    mips, info = _profile_info(cfg, host_mips_1t, load0, wall0)
    return QosMeasurements(
        rate_hz=tuple(float(r) for r in cfg.rate_hz),
        image_scale=tuple(float(s) for s in cfg.image_scale),
        max_kernel_px=tuple(float(k) for k in cfg.max_kernel_px),
        cpu_s_per_frame=cpu_mean,
        cpu_s_per_frame_median=cpu_med,
        detection_rate=det,
        false_detection_rate=fdr,
        host_mips_1t=float(mips),
        info=info,
    )


HEADER = """QoS -> CPU-time measurements of paper 004's landing-marker detector (SduMarkerDetector through
QosDetector), written by alight.evaluation.qos_profile (see its module docstring for the method).
Tables are indexed [image_scale][max_kernel_px] (the axes below); cpu_s_per_frame is host CPU seconds per
processed frame; detection_rate is the fraction of frames with the pad centre in view detected within
tolerance; false_detection_rate the fraction of frames without the pad with any detection.
These are HOST numbers: QosEnergyModel.load(device=..., mode=...) scales them to a device
(alight/energy/devices/*.yaml) with host_mips_1t and the device's cpu_mips_1t and W per busy core."""


def table_text(meas: QosMeasurements, key: str = "mix") -> str:
    """A plain-text table of ``cpu_s_per_frame[key]`` in ms and the detection rates."""
    lines = [f"host CPU ms per frame ({key}); detection rate (visible) / false detections (absent)"]
    lines.append("scale \\ kernel " + "".join(f"{int(k):>18d}" for k in meas.max_kernel_px))
    for i, s in enumerate(meas.image_scale):
        cells = []
        for j in range(len(meas.max_kernel_px)):
            ms = 1e3 * meas.cpu_s_per_frame[key][i, j]
            dr = meas.detection_rate.get("visible")
            fd = meas.false_detection_rate
            d = "" if dr is None else f"{dr[i, j]:.2f}"
            f = "" if fd is None else f"{fd[i, j]:.2f}"
            cells.append(f"{ms:7.2f} {d}/{f}")
        lines.append(f"{s:>14g} " + "".join(f"{c:>18s}" for c in cells))
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m alight.evaluation.qos_profile", description=__doc__.split("\n")[0]
    )
    ap.add_argument("--out", required=True, help="measurements file to write (YAML)")
    ap.add_argument("--quick", action="store_true", help="a seconds-long smoke run (2 x 2 grid, 4 frames)")
    ap.add_argument("--frames-per-kind", type=int, default=None)
    ap.add_argument("--repeats", type=int, default=None)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument(
        "--host-mips", type=float, default=None, help="host 7-Zip rating (default: measure with 7z)"
    )
    args = ap.parse_args(argv)
    cfg = ProfileConfig.quick() if args.quick else ProfileConfig()
    kw: dict[str, Any] = {"seed": args.seed}
    if args.frames_per_kind is not None:
        kw["frames_per_kind"] = args.frames_per_kind
    if args.repeats is not None:
        kw["repeats"] = args.repeats
    cfg = ProfileConfig(**{**cfg.__dict__, **kw})
    meas = run_profile(cfg, host_mips_1t=args.host_mips)
    meas.save(args.out, HEADER)
    print(table_text(meas))
    print(f"host_mips_1t {meas.host_mips_1t:g} ({meas.info['host_mips_1t_source']}); wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
