"""The ``alight`` command.

    alight fly SCENARIO.yaml --out DIR [--seed N]
    alight detect IMAGE... --detector NAME [--camera FILE]
    alight bench [--quick] [--only KEY,...]

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
    out = Path(args.out)
    run = fly_to_dir(scenario, out)
    r = run.result
    err = r["touchdown_error_m"]
    err_txt = "-" if err is None else f"{err:.3f} m"
    print(
        f"{r['preset']} seed {r['seed']}: {r['outcome']}, touchdown error {err_txt}, "
        f"{r['simulated_time_s']:.1f} s simulated in {r['wall_time_s']:.2f} s -> {out / 'report.html'}"
    )
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


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="alight", description="Autonomous landing on moving platforms.")
    parser.add_argument("--version", action="store_true", help="print the version and exit")
    sub = parser.add_subparsers(dest="command")

    fly = sub.add_parser("fly", help="fly one mission and write result.json, the log, plots and report.html")
    fly.add_argument("scenario", help="scenario YAML file")
    fly.add_argument("--out", required=True, help="output directory")
    fly.add_argument("--seed", type=int, default=None, help="override the scenario's seed")
    fly.set_defaults(func=_cmd_fly)

    det = sub.add_parser("detect", help="run a detector on images; one JSON line per image")
    det.add_argument("images", nargs="+")
    det.add_argument("--detector", required=True, help="falanga | aruco | apriltag")
    det.add_argument("--camera", default=None, help="camera calibration (OpenCV YAML) for the pose")
    det.set_defaults(func=_cmd_detect)

    bench = sub.add_parser("bench", help="run the performance benchmarks and print a JSON summary")
    bench.add_argument("--quick", action="store_true", help="fewer repeats (for a smoke test)")
    bench.add_argument("--only", default=None, help="comma-separated benchmark groups to run")
    bench.set_defaults(func=_cmd_bench)
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
