#!/usr/bin/env python3
"""Plot lidar validation waveforms (docs/img/lidar_cases.png) from validation/lidar/cases.csv,
which the test `lidar_cases` writes:

    cargo test --release -p simulator --test lidar_cases -- --nocapture
    python3 tools/plots/lidar_plot.py

Closed forms (the pulse's Gaussian, broadened by the slope or the off-nadir footprint; the
first-order air return by quadrature) are drawn where they exist; the leaf cells show the
simulated first-order waveform with its standard errors. Needs numpy and matplotlib.
"""
import csv
import math
import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
CSV = os.path.join(ROOT, "validation", "lidar", "cases.csv")
PNG = os.path.join(ROOT, "docs", "img", "lidar_cases.png")
C = 0.299792458  # m/ns


def phi(x):
    return 0.5 * (1.0 + math.erf(x / math.sqrt(2.0)))


def rows_of(rows, case):
    pts = []
    for r in rows:
        if r["case"] != case:
            continue
        b = r["bin_height_m"]
        try:
            x = float(b) if b else float(r["time_ns"])
        except ValueError:
            continue
        pts.append((x, float(r["energy"]), float(r["stderr"])))
    pts.sort()
    return np.array(pts)


def gauss_bins(x, width, area, sigma):
    return np.array([area * (phi((c + width / 2) / sigma) - phi((c - width / 2) / sigma)) for c in x])


def main():
    with open(CSV) as f:
        rows = list(csv.DictReader(f))
    fig, axes = plt.subplots(2, 3, figsize=(13, 7.5))
    sz = 0.5 * C * 6.0
    panels = [
        ("A1", "flat ground, 6 ns pulse", 0.15, lambda x: gauss_bins(x, 0.15, 0.3, sz)),
        ("C2", "30° slope", 0.15,
         lambda x: gauss_bins(x, 0.15, 0.3 * math.cos(math.radians(30)),
                              math.hypot(sz, 5.5 * math.tan(math.radians(30))))),
        ("C3", "6° off nadir (time bins, ns)", 1.0,
         lambda x: gauss_bins(x, 1.0, 0.3 * math.cos(math.radians(6)),
                              math.hypot(6.0, 2 * 5.5 * math.tan(math.radians(6)) / C))),
    ]
    for ax, (case, title, _, model) in zip(axes[0], panels):
        d = rows_of(rows, case)
        ax.plot(d[:, 0], model(d[:, 0]), "k-", lw=1, label="closed form")
        ax.errorbar(d[:, 0], d[:, 1], yerr=d[:, 2], fmt=".", ms=3, color="C0", label="simulate")
        ax.set_title(f"{case}: {title}")
        ax.set_xlabel("time (ns)" if case == "C3" else "apparent height (m)")
        ax.set_ylabel("normalised energy per bin")
        ax.legend(fontsize=8)
    # B3a: first-order air returns per 500 m bin against the quadrature.
    ax = axes[1][0]
    d = rows_of(rows, "B3a")
    h, ht, beta = 5e5, 1e4, 0.1 / 1e4
    quad = []
    for c in d[:, 0]:
        lo, hi = max(c - 250.0, 0.0), min(c + 250.0, ht)
        zs = np.linspace(lo, hi, 2001)
        f = beta * np.exp(-2 * beta * (ht - zs)) * (h / (h - zs)) ** 2 / 4
        quad.append(np.trapezoid(f, zs) if hi > lo else 0.0)
    quad = np.array(quad)
    quad[0] += 0.3 * math.exp(-0.2)  # the ground's return is in the bin at 0 m
    ax.semilogy(d[:, 0] / 1e3, quad, "k-", lw=1, label="quadrature (+ ground)")
    ax.semilogy(d[:, 0] / 1e3, d[:, 1], ".", color="C0", label="simulate, first order")
    ax.set_title("B3a: scattering layer, isotropic")
    ax.set_xlabel("apparent height (km)")
    ax.set_ylabel("normalised energy per bin")
    ax.legend(fontsize=8)
    # Leaf cells: first-order waveforms.
    for ax, (case, title) in zip(axes[1][1:], [("D1", "LAI 3 spherical leaves"), ("D4", "HOM cell")]):
        d = rows_of(rows, case)
        ax.errorbar(d[:, 1], d[:, 0], xerr=d[:, 2], fmt=".-", ms=3, color="C2")
        ax.set_title(f"{case}: {title}, first order")
        ax.set_ylabel("apparent height (m)")
        ax.set_xlabel("normalised energy per bin")
    fig.tight_layout()
    fig.savefig(PNG, dpi=110)
    print(f"wrote {PNG}")


if __name__ == "__main__":
    main()
