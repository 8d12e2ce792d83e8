#!/usr/bin/env python3
"""Plot our O2 A-band TOA Stokes I, Q against ARTDECO's 32-stream doubling-adding values
(docs/img/artdeco_o2a.png) from validation/artdeco_o2a/comparison.csv, which the ignored test
`artdeco_o2a_full_spectrum_csv` writes:

    cargo test --release -p simulator --test artdeco_o2a -- --ignored --nocapture
    python3 tools/plots/artdeco_plot.py

Needs numpy and matplotlib (a venv outside the repo).
"""
import csv
import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
CSV = os.path.join(ROOT, "validation", "artdeco_o2a", "comparison.csv")
PNG = os.path.join(ROOT, "docs", "img", "artdeco_o2a.png")


def main():
    with open(CSV) as f:
        rows = list(csv.DictReader(f))
    col = {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}
    w = col["wavelength_nm"]
    bad = col["ref_inconsistent"] > 0.5
    ok = ~bad

    fig, (ax1, ax2) = plt.subplots(
        2, 1, figsize=(11, 7.5), sharex=True, gridspec_kw={"height_ratios": [3, 2]}
    )
    ax1.semilogy(w, col["i_ref"], "-", color="0.6", lw=2.2, label="I, ARTDECO (DA, 32 streams)")
    ax1.semilogy(w, col["i"], "-", color="C0", lw=0.8, label="I, ours")
    ax1.semilogy(w, -col["q_ref"], "-", color="0.8", lw=2.2, label="−Q, ARTDECO")
    ax1.semilogy(w, -col["q"], "-", color="C1", lw=0.8, label="−Q, ours")
    ax1.semilogy(
        w[bad], col["i_ref"][bad], "x", color="C3", ms=8,
        label="ARTDECO not self-consistent (vs. single scattering)",
    )
    ax1.set_ylabel("π·I/(μ0·E0), π·(−Q)/(μ0·E0)")
    ax1.set_title(
        "O2 A-band, Rayleigh + O2, black surface, SZA 30°, VZA 20°, RAA 180° (TOA)"
    )
    ax1.set_ylim(2e-6, 3e-2)
    ax1.legend(loc="lower right", fontsize=8, ncol=2)
    ax1.grid(alpha=0.3)

    for name, c in (("i", "C0"), ("q", "C1")):
        rel = (col[name] / col[name + "_ref"] - 1.0) * 100.0
        se = np.abs(col[name + "_stderr"] / col[name + "_ref"]) * 100.0
        ax2.fill_between(w, -2 * se, 2 * se, color=c, alpha=0.15, lw=0)
        label = name.upper() + ": ours/ARTDECO − 1"
        ax2.plot(w[ok], rel[ok], ".", color=c, ms=2.5, label=label)
    ax2.axhline(0.1, color="k", lw=0.6, ls="--")
    ax2.axhline(-0.1, color="k", lw=0.6, ls="--", label="±0.1 % (reference floor)")
    lim = 0.6
    ax2.set_ylim(-lim, lim)
    for x in w[bad]:
        ax2.annotate("", xy=(x, -lim * 0.97), xytext=(x, -lim * 0.72),
                     arrowprops=dict(arrowstyle="->", color="C3"))
    i_bad = (col["i"][bad] / col["i_ref"][bad] - 1.0) * 100.0
    ax2.text(
        w[bad].max() + 0.03, -lim * 0.85,
        f"{bad.sum()} deepest cores: I {i_bad.min():.1f} … {i_bad.max():.1f} % "
        "(ARTDECO not self-consistent there)",
        color="C3", fontsize=8, va="center",
    )
    ax2.set_ylabel("relative difference [%]\n(shaded: ±2σ of ours)")
    ax2.set_xlabel("wavelength [nm]")
    ax2.legend(loc="upper right", fontsize=8, ncol=3)
    ax2.grid(alpha=0.3)
    fig.tight_layout()
    os.makedirs(os.path.dirname(PNG), exist_ok=True)
    fig.savefig(PNG, dpi=120)
    d = {n: col[n][ok] / col[n + "_ref"][ok] - 1.0 for n in ("i", "q")}
    print(
        f"wrote {PNG}: {len(w)} wavelengths, {bad.sum()} flagged; "
        f"max |I rel diff| {np.abs(d['i']).max():.2e}, max |Q rel diff| {np.abs(d['q']).max():.2e}"
    )


if __name__ == "__main__":
    main()
