"""The ``alight`` command.

    alight fly SCENARIO.yaml --out DIR [--seed N] [--replay] [--mcap] [--bag PATH [--bag-storage S]]
               [--print-config] [--no-warmup] [--autopilot sim|emulator|px4 [--px4 DIR] [--px4-mode M]
               [--px4-speed X] [--setpoint position|rates]]
    alight blocks
    alight detect IMAGE... --detector NAME [--camera FILE]
    alight bench [--quick] [--only KEY,...]
    alight campaign CAMPAIGN.yaml [--out DIR] [--engine local|dask] [--scheduler ADDR] [--workers N]
                    [--no-progress] [--limit N] [--autopilot sim|emulator|px4 [--px4 DIR] [--px4-mode M]]
    alight report DIR
    alight replay LOG --out DIR [--mapping FILE] [--scenario FILE]
    alight sitl SCENARIO.yaml --port PORT [--flavour px4|ardupilot] [--speed X] [--no-lockstep]
    alight bridge --connect udp:HOST:PORT --out DIR [--mode offboard|landing-target] [--arm]
                  [--setpoint rates|position] [--autopilot px4|ardupilot] [--scenario FILE] [--camera SPEC]

Exit status 0 on success, 2 on bad input with one line on stderr that says what is wrong and where.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

from alight.errors import AlightError


def _cmd_fly(args: argparse.Namespace) -> int:
    from alight.evaluation.mission_io import fly_to_dir
    from alight.scenario import load_scenario

    _autopilot_settings(args)
    scenario = load_scenario(args.scenario)
    if args.seed is not None:
        if args.seed < 0:
            raise AlightError(f"--seed must be >= 0, got {args.seed}")
        scenario = scenario.with_seed(args.seed)
    if args.print_config:
        import yaml

        from alight.mission.presets import effective_config

        print(yaml.safe_dump(effective_config(scenario), sort_keys=False), end="")
        return 0
    if args.out is None:
        raise AlightError("--out DIR is required (unless --print-config)")
    out = Path(args.out)
    if args.autopilot in ("px4", "emulator"):
        from alight.interfaces.autopilot_missions import fly_through_command

        if not args.no_warmup:
            _warm_up_before_the_clock(scenario)
        return fly_through_command(scenario, out, args)
    exports = _fly_exports(args, scenario, out)
    if not args.no_warmup:
        _warm_up_before_the_clock(scenario)
    try:
        run = fly_to_dir(scenario, out, replay=args.replay, frame_sinks=[e for e, _ in exports])
    except BaseException:
        for e, _ in exports:
            e.close()
        raise
    for _, finish in exports:
        finish(run)
    r = run.result
    err = r["touchdown_error_m"]
    err_txt = "-" if err is None else f"{err:.3f} m"
    print(
        f"{r['preset']} seed {r['seed']}: {r['outcome']}, touchdown error {err_txt}, "
        f"{r['simulated_time_s']:.1f} s simulated in {r['wall_time_s']:.2f} s -> {out / 'report.html'}"
    )
    return 0


def _warm_up_before_the_clock(scenario: Any) -> None:
    """Compile (or load from numba's cache) the kernels of the scenario's preset and of its blocks (the
    presets that fly them) before the mission's clock starts, so ``wall_time_s`` and the block times in
    result.json hold no compile; says on stderr what it took."""
    from alight.compile.warmup import presets_to_warm_up, warm_up

    presets = presets_to_warm_up([scenario.model_dump(mode="json")])
    preset = ", ".join(presets)
    try:
        rep = warm_up(presets)
    except Exception as err:  # the mission itself will say what is wrong; its compile then is on its clock
        print(f"warm-up ({preset}) failed, the mission's clock may hold the compile: {err}", file=sys.stderr)
        return
    ahead = ""
    if rep.ahead is not None and rep.ahead.helpers:
        a = rep.ahead
        ahead = (
            f" in the flight, after {a.kernels} kernels in {a.helpers} parallel processes ({a.wall_s:.1f} s, "
            f"{a.cpu_s:.1f} s CPU{f'; {len(a.failed)} left to the flight' if a.failed else ''})"
        )
    print(
        f"warm-up ({preset}, before the mission's clock): {rep.wall_s:.2f} s, "
        f"numba compiled {rep.n_signatures} signatures in {rep.compile_s:.2f} s CPU{ahead}",
        file=sys.stderr,
    )


def _camera_of(scenario: Any) -> tuple[Any, Any]:
    """The camera model and mount of the scenario's preset (as the runner builds them)."""
    import numpy as np

    from alight.airframes import load_airframe
    from alight.mission.presets import build_preset

    preset = build_preset(scenario, load_airframe(scenario.airframe), np.random.default_rng(0))
    return preset.camera, preset.mount


def _fly_exports(
    args: argparse.Namespace, scenario: Any, out: Path
) -> list[tuple[Any, Callable[[Any], object]]]:
    """The exporters ``alight fly --mcap`` / ``--bag PATH`` asked for: (frame sink with a ``close``,
    finish(run))."""
    exports: list[tuple[Any, Callable[[Any], object]]] = []
    if args.mcap:
        from alight.interfaces.mcap_export import MCAP_FILE, McapExporter

        out.mkdir(parents=True, exist_ok=True)
        camera, mount = _camera_of(scenario)
        mcap = McapExporter(out / MCAP_FILE, camera=camera, mount=mount)
        exports.append((mcap, lambda run: mcap.finish(run.log, run.mode_history)))
    if args.bag is not None:
        from alight.interfaces.rosbag_writer import BagRecorder

        latency = scenario.perception.latency_s
        try:
            bag = BagRecorder(args.bag, storage=args.bag_storage, latency_s=latency)
        except BaseException:
            for e, _ in exports:
                e.close()
            raise
        exports.append((bag, lambda run: bag.finish(run.log)))
    return exports


def _cmd_blocks(args: argparse.Namespace) -> int:
    from alight.mission.blocks import describe_blocks

    print(describe_blocks())
    return 0


def _cmd_detect(args: argparse.Namespace) -> int:
    from alight.perception.detect_cli import run_detect

    return run_detect(args.images, args.detector, args.camera)


def _cmd_bench(args: argparse.Namespace) -> int:
    from alight.evaluation.bench import run_benchmarks

    only = None if args.only is None else [k.strip() for k in args.only.split(",") if k.strip()]
    summary = run_benchmarks(quick=args.quick, only=only)
    print(json.dumps(summary, indent=2))
    return 0


MISSION_FN_ENV = "ALIGHT_CAMPAIGN_MISSION_FN"
"""Test hook: ``module:function`` replacing the campaign's mission function (see docs/campaigns.md)."""


def _cmd_campaign(args: argparse.Namespace) -> int:
    from alight.campaign.run import CampaignInterrupted, run_campaign

    _autopilot_settings(args)
    if args.workers is not None and args.workers < 1:
        raise AlightError(f"--workers must be >= 1, got {args.workers}")
    if args.limit is not None and args.limit < 1:
        raise AlightError(f"--limit must be >= 1, got {args.limit}")
    mission_fn = os.environ.get(MISSION_FN_ENV) or None
    if mission_fn is not None:
        print(f"alight campaign: missions are {mission_fn} (from {MISSION_FN_ENV})", file=sys.stderr)
    campaign: Any = args.campaign
    if args.limit is not None:
        from alight.campaign.spec import MAX_MISSIONS, count_missions, load_campaign, read_campaign_spec

        # A campaign too big to expand whole can still fly its first missions: expand only those. Below
        # the cap the whole campaign is expanded as always (resuming with another --limit stays possible).
        if count_missions(read_campaign_spec(args.campaign)[0]) > MAX_MISSIONS:
            campaign = load_campaign(args.campaign, limit=args.limit)
    through: dict[str, Any] = {}
    if args.autopilot != "sim":
        through = _autopilot_campaign(args, mission_fn)
        mission_fn = through["mission_fn"]
    try:
        with _environment(through.get("env", {})):
            result = run_campaign(
                campaign,
                args.out,
                engine=args.engine,
                workers=args.workers,
                scheduler=args.scheduler,
                limit=args.limit,
                progress=not args.no_progress,
                mission_fn=mission_fn,
                warmup=True if through else None,
                flown_with=through.get("record"),
            )
    except CampaignInterrupted as stop:
        print(f"alight campaign: {stop.message}", file=sys.stderr)
        return 130
    if result.report_error is not None:
        print(f"alight campaign: warning: report.html not written: {result.report_error}", file=sys.stderr)
    done = result.n_skipped + result.n_run
    shown = result.report_path or result.summary_path
    print(
        f"campaign {result.campaign}: {done}/{result.n_planned} missions recorded "
        f"({result.n_run} flown now, {result.n_errors} errors) in {result.wall_time_s:.1f} s -> {shown}"
    )
    if result.n_views:
        print(
            f"alight campaign: views of {result.n_views} failures drawn (each flown again)", file=sys.stderr
        )
    for problem in result.views_problems[:5]:
        print(f"alight campaign: warning: {problem}", file=sys.stderr)
    if len(result.views_problems) > 5:
        print(f"alight campaign: warning: {len(result.views_problems) - 5} more (views.txt)", file=sys.stderr)
    # Status 1 when nothing flew (every recorded mission is an error: a broken install, preset or
    # cluster), so scripts and CI notice; some errors among results still exit 0, with a count line.
    errors, recorded = result.n_recorded_errors, result.n_recorded
    if recorded and errors == recorded:
        print(f"alight campaign: all {recorded} recorded missions are errors (error.txt)", file=sys.stderr)
        return 1
    if errors:
        print(f"alight campaign: {errors} of {recorded} recorded missions are errors", file=sys.stderr)
    return 0


def _autopilot_campaign(args: argparse.Namespace, mission_fn: str | None) -> dict[str, Any]:
    """``alight campaign --autopilot emulator|px4``: the mission function, the environment its sandboxes
    inherit (the setting) and the lock's record of it (alight.interfaces.autopilot_missions)."""
    from alight.interfaces.autopilot_missions import AUTOPILOT_ENV, MISSION_FNS, AutopilotSetting

    if mission_fn is not None:
        raise AlightError(f"--autopilot: the missions are the autopilot's; unset {MISSION_FN_ENV}")
    if args.engine != "local":
        raise AlightError("--autopilot: missions through an autopilot run on the local engine only")
    px4_dir = None
    if args.autopilot == "px4":
        from alight.interfaces.px4_run import find_px4_build

        px4_dir = str(find_px4_build(args.px4).root)  # refused here in one line, not in every mission
    setting = AutopilotSetting(
        kind=args.autopilot, mode=args.px4_mode, setpoint=args.setpoint, speed=args.px4_speed, px4_dir=px4_dir
    )
    record = {k: v for k, v in setting.record().items() if k != "px4_dir"}  # the machine's, not the setting
    return {
        "mission_fn": MISSION_FNS[args.autopilot],
        "env": {AUTOPILOT_ENV: setting.to_env()},
        "record": record,
    }


@contextlib.contextmanager
def _environment(values: dict[str, str]) -> Iterator[None]:
    """``values`` in this process's environment (which the campaign's sandboxes inherit) while inside."""
    before = {k: os.environ.get(k) for k in values}
    os.environ.update(values)
    try:
        yield
    finally:
        for k, v in before.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _cmd_report(args: argparse.Namespace) -> int:
    from alight.campaign.run import write_report
    from alight.campaign.store import LOCK_JSON, RESULTS_CSV
    from alight.campaign.summary import write_summary

    out = Path(args.dir)
    if not (out / RESULTS_CSV).is_file():
        raise AlightError(f"{out}: no {RESULTS_CSV} (not a campaign output directory)")
    if (out / LOCK_JSON).is_file():
        write_summary(out)  # brings summary.json up to date with results.csv
    try:
        import alight.campaign.report  # noqa: F401
    except ImportError:
        raise AlightError(
            "the campaign report (alight.campaign.report) is not available in this install"
        ) from None
    path, error = write_report(out)
    if error is not None:
        raise AlightError(f"{out}: report not written: {error}")
    print(path)
    return 0


def _cmd_replay(args: argparse.Namespace) -> int:
    from alight.interfaces.replay import replay_to_dir

    out = Path(args.out)
    run = replay_to_dir(args.log, out, mapping=args.mapping, scenario=args.scenario)
    r = run.result
    for warning in r["warnings"]:
        print(f"alight replay: warning: {warning}", file=sys.stderr)
    counts = ", ".join(f"{k} {v}" for k, v in r["messages"].items())
    print(
        f"{r['format']} {r['source']}: {r['duration_s']:.1f} s replayed through {r['preset']} ({counts}); "
        f"{r['frames']} frames, {r['detections']} detections -> {out / 'report.html'}"
    )
    return 0


def _cmd_sitl(args: argparse.Namespace) -> int:
    from alight.interfaces.sitl import SitlConfig, serve
    from alight.scenario import load_scenario

    scenario = load_scenario(args.scenario)
    if args.seed is not None:
        scenario = scenario.with_seed(args.seed)
    if not 0 < args.port < 65535:
        raise AlightError(f"--port must be in 1..65534, got {args.port}")
    config = SitlConfig(
        port=args.port,
        flavour=args.flavour,
        lockstep=not args.no_lockstep,
        speed=args.speed,
        failsafe=args.failsafe,
        offboard_loss_s=args.offboard_loss_s,
    )
    print(
        f"alight sitl: {args.flavour} on udp 127.0.0.1:{args.port}, camera tcp {args.port + 1}",
        file=sys.stderr,
    )
    r = serve(scenario, config)
    err = r["touchdown_error_m"]
    err_txt = "-" if err is None else f"{err:.3f} m"
    print(f"sitl {r['preset']} seed {r['seed']}: {r['outcome']}, touchdown error {err_txt}, "
          f"{r['simulated_time_s']:.1f} s simulated in {r['sitl_wall_time_s']:.1f} s")  # fmt: skip
    return 0


def _cmd_bridge(args: argparse.Namespace) -> int:
    from alight.interfaces.bridge_run import run_bridge
    from alight.interfaces.mavlink_bridge import BridgeConfig

    config = BridgeConfig(mode=args.mode, autopilot=args.autopilot, setpoint=args.setpoint, arm=args.arm)
    r = run_bridge(
        args.connect,
        args.out,
        config,
        scenario_path=args.scenario,
        camera=args.camera,
        max_wall_s=args.max_wall_s,
    )
    err = r["touchdown_error_m"]
    err_txt = "-" if err is None else f"{err:.3f} m"
    print(f"bridge {r['preset']} ({args.mode}): {r['outcome']}, touchdown error {err_txt} -> {args.out}")
    return 0


def _fly_arguments(p: argparse.ArgumentParser) -> None:
    """The arguments of ``alight fly``."""
    p.add_argument("scenario", help="scenario YAML file")
    p.add_argument("--out", default=None, help="output directory (required unless --print-config)")
    p.add_argument("--seed", type=int, default=None, help="override the scenario's seed")
    p.add_argument(
        "--replay", action="store_true", help="also write replay.gif (camera view with detections, top view)"
    )
    p.add_argument("--mcap", action="store_true", help="also write flight.mcap (Foxglove schemas)")
    p.add_argument("--bag", default=None, metavar="PATH", help="also write the flight as a ROS 2 bag at PATH")
    p.add_argument(
        "--bag-storage", choices=("mcap", "sqlite3"), default="mcap", help="storage of --bag (default mcap)"
    )
    p.add_argument(
        "--print-config",
        action="store_true",
        help="print the effective configuration (blocks with parameters after preset + overrides) and exit",
    )
    p.add_argument(
        "--no-warmup",
        action="store_true",
        help="skip the warm-up flight that compiles numba's kernels before the mission's clock starts",
    )
    _autopilot_arguments(p)


def _autopilot_arguments(p: argparse.ArgumentParser) -> None:
    """``--autopilot`` and its settings, for ``alight fly`` and ``alight campaign``
    (:func:`_autopilot_settings` refuses the ones that would not act)."""
    p.add_argument(
        "--autopilot", choices=("sim", "emulator", "px4"), default="sim",
        help="sim: alight's own simulator; emulator: alight's emulated autopilot + the bridge; px4: PX4 SITL",
    )  # fmt: skip
    p.add_argument(
        "--px4", default=None, metavar="DIR", help="px4: the SITL build (bin/px4); else $ALIGHT_PX4_DIR"
    )
    p.add_argument(
        "--px4-mode", choices=("offboard", "landing-target"), default=None,
        help="how the autopilot lands (emulator, px4): offboard setpoints (default) or LANDING_TARGET only",
    )  # fmt: skip
    p.add_argument(
        "--px4-speed", type=float, default=None, help="px4: sim s per wall s at most (default 1; 0: free)"
    )
    p.add_argument(
        "--setpoint", choices=("position", "rates"), default=None,
        help="emulator, px4: offboard setpoints, position (default: its controllers fly) or body rates",
    )  # fmt: skip


AUTOPILOT_DEFAULTS = {"px4": None, "px4_mode": "offboard", "px4_speed": 1.0, "setpoint": "position"}
_ACTS_WITH = {
    "px4": ("px4",),
    "px4_speed": ("px4",),
    "px4_mode": ("emulator", "px4"),
    "setpoint": ("emulator", "px4"),
}


def _autopilot_settings(args: argparse.Namespace) -> None:
    """Refuse, in one line, an autopilot setting that would not act with ``--autopilot``; fill the
    defaults of the others."""
    for name, kinds in _ACTS_WITH.items():
        if getattr(args, name) is not None and args.autopilot not in kinds:
            flag = "--" + name.replace("_", "-")
            raise AlightError(f"{flag} acts only with --autopilot {' or '.join(kinds)}, not {args.autopilot}")
        if getattr(args, name) is None:
            setattr(args, name, AUTOPILOT_DEFAULTS[name])


def _detect_arguments(p: argparse.ArgumentParser) -> None:
    """The arguments of ``alight detect``."""
    p.add_argument("images", nargs="+")
    p.add_argument("--detector", required=True, help="an image detector block (`alight blocks` lists them)")
    p.add_argument("--camera", default=None, help="camera calibration (OpenCV YAML) for the pose")


def _bench_arguments(p: argparse.ArgumentParser) -> None:
    """The arguments of ``alight bench``."""
    p.add_argument("--quick", action="store_true", help="fewer repeats (for a smoke test)")
    p.add_argument("--only", default=None, help="comma-separated benchmark groups to run")


def _campaign_arguments(p: argparse.ArgumentParser) -> None:
    """The arguments of ``alight campaign``."""
    p.add_argument("campaign", help="campaign YAML file")
    p.add_argument("--out", default=None, help="output directory (default runs/<campaign name>)")
    p.add_argument("--engine", choices=("local", "dask"), default="local", help="local processes or Dask")
    p.add_argument("--scheduler", default=None, help="Dask scheduler address (default: a local cluster)")
    p.add_argument("--workers", type=int, default=None, help="worker processes (default: CPU count)")
    p.add_argument("--no-progress", action="store_true", help="no progress line on stderr")
    p.add_argument("--limit", type=int, default=None, help="only the first N missions of the campaign")
    _autopilot_arguments(p)


def _report_arguments(p: argparse.ArgumentParser) -> None:
    """The arguments of ``alight report``."""
    p.add_argument("dir", help="campaign output directory")


def _replay_arguments(p: argparse.ArgumentParser) -> None:
    """The arguments of ``alight replay``."""
    p.add_argument("log", help=".ulg, .bag, a ROS 2 bag directory, .db3 or .mcap")
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--mapping", default=None, help="topic mapping YAML (default: the packaged one)")
    p.add_argument("--scenario", default=None, help="scenario YAML whose preset to run (default falanga2017)")


def _sitl_arguments(p: argparse.ArgumentParser) -> None:
    """The arguments of ``alight sitl``."""
    p.add_argument("scenario", help="scenario YAML file")
    p.add_argument("--port", type=int, required=True, help="UDP port to listen on (camera: PORT + 1, TCP)")
    p.add_argument("--seed", type=int, default=None, help="override the scenario's seed")
    p.add_argument(
        "--flavour", choices=("px4", "ardupilot"), default="px4", help="which autopilot to emulate"
    )
    p.add_argument(
        "--speed", type=float, default=0.0, help="cap on simulated/wall time (0: lockstep, no cap)"
    )
    p.add_argument("--no-lockstep", action="store_true", help="do not wait for the companion (real time)")
    p.add_argument("--failsafe", choices=("hold", "land"), default="hold", help="action on offboard loss")
    p.add_argument("--offboard-loss-s", type=float, default=None, help="COM_OF_LOSS_T / GUID_TIMEOUT (s)")


def _bridge_arguments(p: argparse.ArgumentParser) -> None:
    """The arguments of ``alight bridge``."""
    p.add_argument("--connect", required=True, help="udp:HOST:PORT (connect), udpin:HOST:PORT, serial device")
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--mode", choices=("offboard", "landing-target"), default="offboard")
    p.add_argument("--autopilot", choices=("px4", "ardupilot"), default="px4")
    p.add_argument("--setpoint", choices=("rates", "position"), default="rates", help="offboard setpoints")
    p.add_argument("--arm", action="store_true", help="allow the bridge to arm the vehicle")
    p.add_argument(
        "--scenario", default=None, help="scenario YAML choosing the preset (default: the emulator's)"
    )
    p.add_argument(
        "--camera", default=None, help="tcp:HOST:PORT, device index, file or URL (default: PORT + 1)"
    )
    p.add_argument("--max-wall-s", type=float, default=None, help="stop after this much wall time")


_Command = tuple[
    str, str, Callable[[argparse.ArgumentParser], None] | None, Callable[[argparse.Namespace], int]
]


def build_parser() -> argparse.ArgumentParser:
    """The `alight` command line: one subcommand per row of the table, its arguments added by a helper."""
    parser = argparse.ArgumentParser(prog="alight", description="Autonomous landing on moving platforms.")
    parser.add_argument("--version", action="store_true", help="print the version and exit")
    sub = parser.add_subparsers(dest="command")
    commands: tuple[_Command, ...] = (
        (
            "fly",
            "fly one mission and write result.json, the log, plots and report.html",
            _fly_arguments,
            _cmd_fly,
        ),
        ("blocks", "list every block, its parameters and what it works with", None, _cmd_blocks),
        ("detect", "run a detector on images; one JSON line per image", _detect_arguments, _cmd_detect),
        ("bench", "run the performance benchmarks and print a JSON summary", _bench_arguments, _cmd_bench),
        (
            "campaign",
            "fly a campaign's missions; results.csv, summary.json, report.html (resumable)",
            _campaign_arguments,
            _cmd_campaign,
        ),
        ("report", "(re)write a campaign's summary.json and report.html", _report_arguments, _cmd_report),
        (
            "replay",
            "run perception and estimation on a recorded flight (PX4 ULog, ROS 1/2 bag, MCAP)",
            _replay_arguments,
            _cmd_replay,
        ),
        (
            "sitl",
            "serve a scenario's world as an emulated autopilot over MAVLink (UDP)",
            _sitl_arguments,
            _cmd_sitl,
        ),
        (
            "bridge",
            "run the pipeline against an autopilot over MAVLink; result.json, report",
            _bridge_arguments,
            _cmd_bridge,
        ),
    )
    for name, help_text, add_arguments, func in commands:
        p = sub.add_parser(name, help=help_text)
        if add_arguments is not None:
            add_arguments(p)
        p.set_defaults(func=func)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.version:
        from alight import __version__

        print(__version__)
        return 0
    if args.command is None:
        parser.print_help(sys.stderr)
        return 2
    try:
        return int(args.func(args))
    except AlightError as err:
        print(f"alight {args.command}: {err}", file=sys.stderr)
        return 2
    except ModuleNotFoundError as err:
        from alight.interfaces.optional_deps import missing_dependency_message

        message = missing_dependency_message(err)
        if message is None:
            raise
        print(f"alight {args.command}: {message}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"alight {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
