#!/usr/bin/env python3
"""Plot the canopy benchmarks' principal-plane BRF (total, single, multiple, ±2σ) from the
`results.csv` files kept in validation/canopy/ (docs/img/canopy_principal_plane.png).

Signed view zenith as in the RAMI/ROMC principal plane: negative on the Sun's side (our view
azimuth 90°, the hot spot at −SZA), positive opposite (270°). Needs matplotlib (a venv outside
the repo); from the repo root:

    python3 tools/plots/canopy_plot.py
"""
import csv
import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

CASES = [("hom", "RAMI-like HOM (LAI 3, red)"), ("het01", "ROMC HET01 floating spheres"),
         ("het04", "ROMC HET04 real zoom-in"), ("het06", "ROMC HET06 conifer forest")]


def load(path):
    rows = []
    with open(path) as f:
        for r in csv.DictReader(f):
            if r["measure"] != "principal_plane":
                continue
            vza, vaa = float(r["vza"]), float(r["vaa"])
            signed = -vza if abs(vaa - 90.0) < 1e-6 else vza
            rows.append((signed, float(r["brf"]), float(r["brf_stderr"]),
                         float(r["brf_single"]), float(r["brf_multiple"])))
    rows.sort()
    return rows


def main():
    fig, axes = plt.subplots(2, 2, figsize=(11, 8))
    for ax, (case, title) in zip(axes.flat, CASES):
        path = os.path.join("validation", "canopy", f"{case}_results.csv")
        if not os.path.exists(path):
            ax.set_title(f"{title}: no results")
            continue
        r = load(path)
        z = [x[0] for x in r]
        ax.errorbar(z, [x[1] for x in r], yerr=[2 * x[2] for x in r], fmt="k.-", ms=3,
                    label="total (±2σ)")
        ax.plot(z, [x[3] for x in r], "b--", label="single")
        ax.plot(z, [x[4] for x in r], "r:", label="multiple")
        ax.set_title(title, fontsize=10)
        ax.set_xlabel("signed view zenith [deg] (negative: Sun's side)")
        ax.set_ylabel("BRF")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    os.makedirs("docs/img", exist_ok=True)
    fig.savefig("docs/img/canopy_principal_plane.png", dpi=90)
    print("wrote docs/img/canopy_principal_plane.png")


if __name__ == "__main__":
    main()
