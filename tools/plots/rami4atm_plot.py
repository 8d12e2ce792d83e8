#!/usr/bin/env python3
"""Principal-plane TOA band BRF: our simulator vs the Eradiate RAMI4ATM references (hom00).

Reads the per-case CSVs written by the ignored test `full_run` of
`simulator/tests/rami4atm.rs` (validation/rami4atm/<case>.csv: vza, ours_brf, ours_stderr,
ref_brf, ref_stderr, rel_diff, z, ...) and writes docs/img/rami4atm.png: for each case, the BRF
(reference with ±2σ bars, ours as a line with a ±2σ band) and below it the relative difference
ours/ref − 1 with the ±2σ band of the combined standard error.

Usage (from the repository root):
    python3 tools/plots/rami4atm_plot.py [--out docs/img/rami4atm.png] [CASE ...]
Needs matplotlib (e.g. `python3 -m venv /tmp/plot-venv && /tmp/plot-venv/bin/pip install
matplotlib`).
"""

import argparse
import csv
import math
import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

ROOT = os.path.normpath(os.path.join(os.path.dirname(__file__), "..", ".."))
DEFAULT_CASES = [
    ("hom00_whi_s00s_m04", "white Lambertian, Rayleigh"),
    ("hom00_bla_sd2s_m03", "black, Rayleigh + desert τ 0.2 (B3)"),
    ("hom00_rpv_sd2s_m04", "RPV, Rayleigh + desert τ 0.2"),
    ("hom00_rpv_0d6s_m04", "RPV, desert τ 0.6 (no air)"),
    ("hom00_rpv_sc6s_m04", "RPV, Rayleigh + continental τ 0.6"),
    ("hom00_rpv_ed2s_m04", "RPV, air + gas abs. + desert τ 0.2"),
]


def read(case):
    path = os.path.join(ROOT, "validation", "rami4atm", f"{case}.csv")
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    cols = {k: [float(r[k]) for r in rows] for k in rows[0]}
    order = sorted(range(len(rows)), key=lambda i: cols["vza"][i])
    return {k: [v[i] for i in order] for k, v in cols.items()}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=os.path.join(ROOT, "docs", "img", "rami4atm.png"))
    ap.add_argument("cases", nargs="*")
    args = ap.parse_args()
    cases = [(c, "") for c in args.cases] if args.cases else DEFAULT_CASES

    ncol = 3
    nrow = math.ceil(len(cases) / ncol)
    fig = plt.figure(figsize=(4.6 * ncol, 4.4 * nrow))
    outer = fig.add_gridspec(nrow, ncol, hspace=0.35, wspace=0.28)
    for i, (case, title) in enumerate(cases):
        d = read(case)
        inner = outer[i // ncol, i % ncol].subgridspec(2, 1, height_ratios=[3, 1.3], hspace=0.05)
        ax = fig.add_subplot(inner[0])
        ax2 = fig.add_subplot(inner[1], sharex=ax)
        v = d["vza"]
        lo = [o - 2 * s for o, s in zip(d["ours_brf"], d["ours_stderr"])]
        hi = [o + 2 * s for o, s in zip(d["ours_brf"], d["ours_stderr"])]
        ax.fill_between(v, lo, hi, color="C0", alpha=0.3, lw=0)
        ax.plot(v, d["ours_brf"], color="C0", lw=1.2, label="this simulator")
        ax.errorbar(
            v,
            d["ref_brf"],
            yerr=[2 * s for s in d["ref_stderr"]],
            fmt="o",
            ms=2.5,
            color="C3",
            elinewidth=0.8,
            label="Eradiate reference",
        )
        ax.set_title(f"{case}\n{title}" if title else case, fontsize=9)
        ax.set_ylabel("band BRF")
        ax.tick_params(labelbottom=False)
        ax.grid(alpha=0.3)
        if i == 0:
            ax.legend(fontsize=8, loc="lower center")
        rel = [100 * r for r in d["rel_diff"]]
        sig = [
            200 * math.hypot(so / o, sr / r)
            for o, so, r, sr in zip(d["ours_brf"], d["ours_stderr"], d["ref_brf"], d["ref_stderr"])
        ]
        ax2.fill_between(v, [-s for s in sig], sig, color="0.6", alpha=0.4, lw=0, label="±2σ")
        ax2.axhline(0, color="k", lw=0.6)
        ax2.plot(v, rel, ".-", color="C0", ms=3, lw=0.8)
        ax2.set_ylabel("ours/ref − 1 [%]", fontsize=8)
        ax2.set_xlabel("signed view zenith [°] (+ = Sun side)")
        ax2.grid(alpha=0.3)
    fig.suptitle(
        "RAMI4ATM hom00 TOA principal plane, SZA 30°, Sentinel-2A MSI band-weighted BRF", fontsize=11
    )
    os.makedirs(os.path.dirname(args.out), exist_ok=True)
    fig.savefig(args.out, dpi=110, bbox_inches="tight")
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
