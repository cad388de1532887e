"""The ``alight`` command.

    alight fly SCENARIO.yaml --out DIR [--seed N] [--print-config]
    alight blocks
    alight detect IMAGE... --detector NAME [--camera FILE]
    alight bench [--quick] [--only KEY,...]
    alight campaign CAMPAIGN.yaml [--out DIR] [--engine local|dask] [--scheduler ADDR] [--workers N]
                    [--no-progress] [--limit N]
    alight report DIR

Exit status 0 on success, 2 on bad input with one line on stderr that says what is wrong and where.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from alight.errors import AlightError


def _cmd_fly(args: argparse.Namespace) -> int:
    from alight.evaluation.mission_io import fly_to_dir
    from alight.scenario import load_scenario

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
    run = fly_to_dir(scenario, out, replay=args.replay)
    r = run.result
    err = r["touchdown_error_m"]
    err_txt = "-" if err is None else f"{err:.3f} m"
    print(
        f"{r['preset']} seed {r['seed']}: {r['outcome']}, touchdown error {err_txt}, "
        f"{r['simulated_time_s']:.1f} s simulated in {r['wall_time_s']:.2f} s -> {out / 'report.html'}"
    )
    return 0


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
    import os

    from alight.campaign.run import CampaignInterrupted, run_campaign

    if args.workers is not None and args.workers < 1:
        raise AlightError(f"--workers must be >= 1, got {args.workers}")
    if args.limit is not None and args.limit < 1:
        raise AlightError(f"--limit must be >= 1, got {args.limit}")
    mission_fn = os.environ.get(MISSION_FN_ENV) or None
    if mission_fn is not None:
        print(f"alight campaign: missions are {mission_fn} (from {MISSION_FN_ENV})", file=sys.stderr)
    try:
        result = run_campaign(
            args.campaign,
            args.out,
            engine=args.engine,
            workers=args.workers,
            scheduler=args.scheduler,
            limit=args.limit,
            progress=not args.no_progress,
            mission_fn=mission_fn,
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
    return 0


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


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="alight", description="Autonomous landing on moving platforms.")
    parser.add_argument("--version", action="store_true", help="print the version and exit")
    sub = parser.add_subparsers(dest="command")

    fly = sub.add_parser("fly", help="fly one mission and write result.json, the log, plots and report.html")
    fly.add_argument("scenario", help="scenario YAML file")
    fly.add_argument("--out", default=None, help="output directory (required unless --print-config)")
    fly.add_argument("--seed", type=int, default=None, help="override the scenario's seed")
    fly.add_argument(
        "--replay", action="store_true", help="also write replay.gif (camera view with detections, top view)"
    )
    fly.add_argument(
        "--print-config",
        action="store_true",
        help="print the effective configuration (blocks with parameters after preset + overrides) and exit",
    )
    fly.set_defaults(func=_cmd_fly)

    blk = sub.add_parser("blocks", help="list every block, its parameters and what it works with")
    blk.set_defaults(func=_cmd_blocks)

    det = sub.add_parser("detect", help="run a detector on images; one JSON line per image")
    det.add_argument("images", nargs="+")
    det.add_argument("--detector", required=True, help="falanga | aruco | apriltag | nfold | sdu | red")
    det.add_argument("--camera", default=None, help="camera calibration (OpenCV YAML) for the pose")
    det.set_defaults(func=_cmd_detect)

    bench = sub.add_parser("bench", help="run the performance benchmarks and print a JSON summary")
    bench.add_argument("--quick", action="store_true", help="fewer repeats (for a smoke test)")
    bench.add_argument("--only", default=None, help="comma-separated benchmark groups to run")
    bench.set_defaults(func=_cmd_bench)

    camp = sub.add_parser(
        "campaign", help="fly a campaign's missions; results.csv, summary.json, report.html (resumable)"
    )
    camp.add_argument("campaign", help="campaign YAML file")
    camp.add_argument("--out", default=None, help="output directory (default runs/<campaign name>)")
    camp.add_argument("--engine", choices=("local", "dask"), default="local", help="local processes or Dask")
    camp.add_argument("--scheduler", default=None, help="Dask scheduler address (default: a local cluster)")
    camp.add_argument("--workers", type=int, default=None, help="worker processes (default: CPU count)")
    camp.add_argument("--no-progress", action="store_true", help="no progress line on stderr")
    camp.add_argument("--limit", type=int, default=None, help="only the first N missions of the campaign")
    camp.set_defaults(func=_cmd_campaign)

    rep = sub.add_parser("report", help="(re)write a campaign's summary.json and report.html")
    rep.add_argument("dir", help="campaign output directory")
    rep.set_defaults(func=_cmd_report)
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
    except KeyboardInterrupt:
        print(f"alight {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
