"""Compute energy per landing against quality of service, from a QoS campaign's results.csv.

    python benchmarks/energy_qos_plot.py runs/zamanakos_sdu_qos_sweep [--out docs/energy_qos.png]

One point per setting (the phase-adaptive policy and each fixed setting): mean compute energy of the
landed missions (J) against the success rate with its Wilson 95% interval; a table on stdout with the
saving of each setting against the fixed highest quality, paired on the same seeds (the campaign flies
every setting on the same seeds: ``same_seeds_across``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from alight.campaign.results import read_rows  # noqa: E402
from alight.campaign.summary import wilson95  # noqa: E402
from alight.errors import AlightError  # noqa: E402


def _label(row: dict[str, str]) -> str:
    if row.get("energy.qos") == "phase":
        return "phase-adaptive"
    r, s, k = (row.get(f"energy.fixed.{n}", "") for n in ("rate_hz", "image_scale", "max_kernel_px"))
    return f"fixed {float(r):g} Hz, x{float(s):g}, k<={int(float(k))}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("campaign_dir")
    ap.add_argument("--out", default=None, help="PNG path (default: <campaign_dir>/energy_qos.png)")
    args = ap.parse_args(argv)
    path = Path(args.campaign_dir) / "results.csv"
    if not path.is_file():
        print(f"energy_qos_plot: {path} not found", file=sys.stderr)
        return 2
    try:
        rows = read_rows(path)  # the campaign package's one reader of results.csv (checked header and rows)
    except AlightError as err:
        print(f"energy_qos_plot: {err}", file=sys.stderr)
        return 2
    groups: dict[str, list[dict[str, str]]] = {}
    for row in rows:
        groups.setdefault(_label(row), []).append(row)
    stats = []
    for label, rs in groups.items():
        flown = [r for r in rs if r["outcome"] != "error"]
        landed = [r for r in flown if r["outcome"] == "landed"]
        k, n = len(landed), len(flown)
        lo, hi = wilson95(k, n) or (float("nan"), float("nan"))
        energy = [float(r["energy_compute_J"]) for r in landed if r["energy_compute_J"]]
        by_seed = {r["seed"]: float(r["energy_compute_J"]) for r in flown if r["energy_compute_J"]}
        stats.append((label, k, n, lo, hi, float(np.mean(energy)) if energy else float("nan"), by_seed))
    top = next((s for s in stats if s[0].startswith("fixed 30 Hz, x1,")), None)
    print("| setting | landed | success [95% CI] | compute J per landing | saving vs highest (paired) |")
    print("|---|---|---|---|---|")
    for label, k, n, lo, hi, e, by_seed in sorted(stats, key=lambda s: -s[5] if s[5] == s[5] else 0):
        saving = ""
        if top is not None and label != top[0]:
            seeds = sorted(set(by_seed) & set(top[6]))
            if seeds:
                ratio = sum(by_seed[s] for s in seeds) / sum(top[6][s] for s in seeds)
                saving = f"{100 * (1 - ratio):.0f}% over {len(seeds)} seeds"
        print(f"| {label} | {k}/{n} | {k / max(n, 1):.0%} [{lo:.0%}, {hi:.0%}] | {e:.2f} | {saving} |")
    fig, ax = plt.subplots(figsize=(7.5, 4.5), dpi=110)
    for i, (label, k, n, lo, hi, e, _) in enumerate(sorted(stats, key=lambda s: s[5])):
        rate = k / max(n, 1)
        ax.errorbar(e, rate, yerr=[[rate - lo], [hi - rate]], fmt="o", capsize=4,
                    color="#d1242f" if label == "phase-adaptive" else "#0969da")  # fmt: skip
        # labels alternate above and below their points, so neighbours at similar energy stay readable
        ax.annotate(label, (e, rate), textcoords="offset points", xytext=(6, 8 if i % 2 else -16), fontsize=8)
    ax.set_xlabel("compute energy per landing (J, Jetson Nano 10 W)")
    ax.set_ylabel("success rate (Wilson 95%)")
    ax.set_ylim(0, 1.1)
    ax.grid(alpha=0.3)
    ax.set_title("zamanakos_sdu: quality of service against compute energy")
    fig.tight_layout()
    out = Path(args.out) if args.out else Path(args.campaign_dir) / "energy_qos.png"
    fig.savefig(out)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
