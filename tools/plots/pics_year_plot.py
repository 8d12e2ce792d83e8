#!/usr/bin/env python3
"""Seasonal cycle of a PICS batch: TOA band reflectance (±2σ), solar zenith angle and Earth–Sun
distance per acquisition, from the `pics.csv` written by `simulate pics`.

Usage (from the repository root):
    ./target/release/simulate pics acq365.csv --site examples/pics/libya4_site.toml -o out/pics365
    python3 tools/plots/pics_year_plot.py out/pics365/pics.csv [--out docs/img/pics_year.png]
Needs matplotlib (e.g. `python3 -m venv /tmp/plot-venv && /tmp/plot-venv/bin/pip install
matplotlib`).
"""

import argparse
import csv
import datetime
import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

ROOT = os.path.normpath(os.path.join(os.path.dirname(__file__), "..", ".."))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("csv")
    ap.add_argument("--out", default=os.path.join(ROOT, "docs", "img", "pics_year.png"))
    ap.add_argument("--title", default="Libya-4 example site (examples/pics/libya4_site.toml)")
    args = ap.parse_args()
    with open(args.csv, newline="") as f:
        rows = list(csv.DictReader(f))
    t = [datetime.datetime.fromisoformat(r["time_utc"].replace("Z", "+00:00")) for r in rows]
    day = [x.timetuple().tm_yday for x in t]
    refl = [float(r["reflectance"]) for r in rows]
    se = [float(r["reflectance_stderr"]) for r in rows]
    sza = [float(r["sza"]) for r in rows]
    dist = [float(r["earth_sun_distance_au"]) for r in rows]
    fig, ax = plt.subplots(1, 3, figsize=(12, 3.4))
    ax[0].fill_between(
        day, [r - 2 * s for r, s in zip(refl, se)], [r + 2 * s for r, s in zip(refl, se)],
        color="tab:blue", alpha=0.3, lw=0, label="±2σ",
    )
    ax[0].plot(day, refl, lw=0.8, color="tab:blue", label="reflectance")
    ax[0].set_ylabel(f"{rows[0]['srf']} TOA reflectance")
    ax[0].legend(fontsize=8)
    ax[1].plot(day, sza)
    ax[1].set_ylabel("SZA [deg] (SPA)")
    ax[2].plot(day, dist)
    ax[2].set_ylabel("Earth–Sun distance [AU]")
    for a in ax:
        a.set_xlabel(f"day of {t[0].year}")
        a.grid(alpha=0.3)
    fig.suptitle(f"{args.title}, {t[0].strftime('%H:%M')} UTC, vza {rows[0]['vza']}°", fontsize=10)
    fig.tight_layout()
    fig.savefig(args.out, dpi=100)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
