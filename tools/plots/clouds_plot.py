#!/usr/bin/env python3
"""Plot the 3D-cloud validation outputs (docs/img/clouds_i3rc.png) from
validation/clouds/i3rc.csv, which the example `cloud_cases` writes:

    cargo run --release -p simulator --example cloud_cases -- ../shared/clouds validation/clouds/i3rc.csv
    python3 tools/plots/clouds_plot.py

Panels: I3RC case 1 (step cloud) per-column R, T and nadir radiance Iu for the four
experiments with their standard errors (the column optical depths 2 | 18 are marked); case 2
(MMCR) R and T of experiment 4 beside the column optical depth; case 3 (Landsat) R of
experiment 1 as an image; the IPRT C2 cube's nadir radiance (geometry 5) and its view from the
ground (geometry 1). The references are held back, so nothing here is compared: the figure
shows what was made (shadows on the +x side for SZA 60, channelling through thin columns, the
cube's bright side and shadow). Needs numpy and matplotlib.
"""
import csv
import os
from collections import defaultdict

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
CSV = os.environ.get("CLOUDS_CSV", os.path.join(ROOT, "validation", "clouds", "i3rc.csv"))
PNG = os.path.join(ROOT, "docs", "img", "clouds_i3rc.png")
KIT = os.environ.get("CLOUDS_KIT", os.path.join(ROOT, "..", "shared", "clouds"))


def load():
    data = defaultdict(dict)
    with open(CSV) as f:
        for r in csv.DictReader(f):
            key = (r["case"], int(r["exp"]), r["quantity"])
            data[key][int(r["column_index"])] = (float(r["value"]), float(r["stderr"]))
    out = {}
    for k, d in data.items():
        idx = sorted(d)
        out[k] = (np.array([d[i][0] for i in idx]), np.array([d[i][1] for i in idx]))
    return out


def main():
    d = load()
    fig = plt.figure(figsize=(15, 9))
    x1 = np.arange(1, 33)
    for e in range(1, 5):
        ax = fig.add_subplot(3, 4, e)
        for q, c in (("R", "tab:blue"), ("T", "tab:green"), ("Iu", "tab:red")):
            if ("1", e, q) in d:
                v, s = d[("1", e, q)]
                ax.errorbar(x1, v, yerr=s, color=c, label=q, lw=1, capsize=1)
        ax.axvline(16.5, color="grey", ls=":")
        ax.set_title(f"I3RC case 1 exp {e} (SZA {'0' if e in (1, 3) else '60'}, "
                     f"ω {'1' if e < 3 else '0.99'})", fontsize=9)
        ax.set_xlabel("column (τ 2 | τ 18)", fontsize=8)
        if e == 1:
            ax.legend(fontsize=8)
    ax = fig.add_subplot(3, 4, (5, 6))
    x2 = np.arange(1, 641)
    for q, c in (("R", "tab:blue"), ("T", "tab:green")):
        v, s = d[("2", 4, q)]
        ax.fill_between(x2, v - s, v + s, color=c, alpha=0.4)
        ax.plot(x2, v, color=c, lw=0.6, label=q)
    tau_file = os.path.join(KIT, "i3rc_phase1", "case2", "mmcr_tau_32km_020898")
    if os.path.exists(tau_file):
        tau = np.loadtxt(tau_file).sum(axis=0)
        ax2 = ax.twinx()
        ax2.plot(x2, tau, color="k", lw=0.5, alpha=0.6)
        ax2.set_ylabel("column τ", fontsize=8)
    ax.set_title("I3RC case 2 (MMCR) exp 4: SZA 60, ω 0.99", fontsize=9)
    ax.set_xlabel("column", fontsize=8)
    ax.legend(fontsize=8, loc="upper left")
    ax = fig.add_subplot(3, 4, 7)
    v, _ = d[("3", 1, "R")]
    im = ax.imshow(v.reshape(128, 128), origin="lower", cmap="gray", vmin=0, vmax=1)
    fig.colorbar(im, ax=ax, fraction=0.046)
    ax.set_title("case 3 (Landsat) exp 1: R", fontsize=9)
    ax = fig.add_subplot(3, 4, 8)
    v, _ = d[("3", 2, "Id")]
    im = ax.imshow(v.reshape(128, 128), origin="lower", cmap="magma")
    fig.colorbar(im, ax=ax, fraction=0.046)
    ax.set_title("case 3 exp 2: Id (SZA 60, sun at low x)", fontsize=9)
    for k, (g, title) in enumerate(((5, "IPRT C2 geometry 5: nadir from 5 km"),
                                    (6, "geometry 6: θ 140°, φ 0"),
                                    (1, "geometry 1: from the ground, θ 40°"))):
        ax = fig.add_subplot(3, 4, 9 + k)
        v, _ = d[("iprt_c2", g, "I")]
        # column_index = (ix − 1)·70 + iy: x runs along the first axis.
        img = v.reshape(70, 70).T
        im = ax.imshow(img, origin="lower", extent=[0, 7, 0, 7], cmap="viridis")
        fig.colorbar(im, ax=ax, fraction=0.046)
        ax.set_title(title + " (L/E0)", fontsize=9)
        ax.set_xlabel("x, km", fontsize=8)
    ax = fig.add_subplot(3, 4, 12)
    v, s = d[("iprt_c2", 6, "I")]
    rel = np.where(v > 0, s / np.maximum(v, 1e-30), np.nan)
    ax.hist(rel[np.isfinite(rel)] * 100, bins=50)
    ax.set_title("IPRT C2 geometry 6: rel. stderr per pixel, %", fontsize=9)
    fig.tight_layout()
    fig.savefig(PNG, dpi=90)
    print("wrote", PNG)


if __name__ == "__main__":
    main()
