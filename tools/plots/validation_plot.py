#!/usr/bin/env python3
"""Plot simulate's principal-plane BRF against the DISORT references (docs/img/*.png).

Runs the release `simulate` binary on experiments built from the reference cases, then plots the
Monte Carlo BRF (with ±2σ bars) over the DISORT curve, and the relative difference in units of
the standard error. Needs numpy and matplotlib (a venv outside the repo); from the repo root:

    python3 tools/plots/validation_plot.py
"""
import csv
import os
import subprocess
import sys
import tempfile

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
BIN = os.path.join(ROOT, "target", "release", "simulate")
DATA = os.path.join(ROOT, "simulator", "tests", "data")


def ref_rows(path, pred):
    with open(path) as f:
        return [r for r in csv.DictReader(f) if pred(r)]


def run(exp_text):
    with tempfile.TemporaryDirectory() as d:
        p = os.path.join(d, "exp.toml")
        with open(p, "w") as f:
            f.write(exp_text)
        subprocess.run([BIN, "run", p, "-o", d, "--quiet"], check=True, capture_output=True)
        with open(os.path.join(d, "results.csv")) as f:
            return list(csv.DictReader(f))


def principal_plane(rows):
    rows = [r for r in rows if r["plane"] == "principal" and r["quantity"] == "brf"]
    rows.sort(key=lambda r: float(r["signed_vza"]))
    return [float(r["signed_vza"]) for r in rows], [float(r["value"]) for r in rows]


def experiment(atmosphere, surface, sza, spp):
    zen = ", ".join(str(float(z)) for z in range(-85, 86, 5))
    return f"""seed = 1
[spectral]
wavelengths = [550.0]
{atmosphere}
[surface]
{surface}
[illumination]
type = "directional"
zenith = {sza}
azimuth = 0.0
[[measures]]
id = "pp"
type = "mdistant"
azimuth = 0.0
zeniths = [{zen}]
spp = {spp}
"""


CASES = [
    (
        "caseA_tau0.5_alb0.3_sza30",
        "Rayleigh τ=0.5, Lambertian 0.3, SZA 30°",
        os.path.join(DATA, "fixtures", "caseA_disort_public.csv"),
        lambda r: r["tau"] == "0.5" and r["albedo"] == "0.3" and r["sza"] == "30.0",
        '[atmosphere]\ntype = "homogeneous"\noptical_thickness = 0.5',
        'type = "lambertian"\nreflectance = 0.3',
        30.0,
    ),
    (
        "caseB2_hg0.7",
        "HG g=0.7 τ=0.5, Lambertian 0.3, SZA 30°",
        os.path.join(DATA, "disort", "caseB.csv"),
        lambda r: r["case"] == "B2",
        '[atmosphere]\ntype = "homogeneous"\noptical_thickness = 0.5\nphase = { type = "hg", g = 0.7 }',
        'type = "lambertian"\nreflectance = 0.3',
        30.0,
    ),
    (
        "caseC4_waso",
        "IPRT waso (tabulated) τ=1, Lambertian 0.3, SZA 30°",
        os.path.join(DATA, "disort", "caseC.csv"),
        lambda r: r["case"] == "C4",
        f'[atmosphere]\ntype = "homogeneous"\noptical_thickness = 1.0\nsingle_scattering_albedo = 0.9756828105008852\n'
        f'phase = {{ type = "tabulated", file = "{os.path.join(DATA, "fixtures", "waso.mie.cdf")}" }}',
        'type = "lambertian"\nreflectance = 0.3',
        30.0,
    ),
    (
        "caseE1_rpv",
        "Rayleigh τ=0.2 over RPV (0.1, 0.543, −0.29), SZA 30°",
        os.path.join(DATA, "disort", "caseE.csv"),
        lambda r: r["case"] == "E1",
        '[atmosphere]\ntype = "homogeneous"\noptical_thickness = 0.2',
        'type = "rpv"\nrho_0 = 0.1\nk = 0.543\ng = -0.29',
        30.0,
    ),
]


def main():
    spp = int(sys.argv[1]) if len(sys.argv) > 1 else 1_000_000
    fig, axes = plt.subplots(2, len(CASES), figsize=(4.2 * len(CASES), 6.5), sharex=True,
                             gridspec_kw={"height_ratios": [3, 1.3]})
    for k, (name, title, ref_path, pred, atm, surf, sza) in enumerate(CASES):
        x_ref, y_ref = principal_plane(ref_rows(ref_path, pred))
        exp = experiment(atm.replace("waso.mie.cdf\"", "waso.mie.cdf\", wavelength = 350.0"), surf, sza, spp)
        out = run(exp)
        # hplane rows are in the order of the zeniths: -85 … 85.
        y = [float(r["brf"]) for r in out]
        e = [float(r["brf_stderr"]) for r in out]
        ax, bx = axes[0][k], axes[1][k]
        ax.plot(x_ref, y_ref, "k-", lw=1.2, label="DISORT")
        ax.errorbar(x_ref, y, yerr=[2 * s for s in e], fmt="o", ms=3, color="C3", label="simulate (±2σ)")
        ax.set_title(title, fontsize=9)
        ax.axvline(sza, color="0.8", lw=0.8)
        ax.set_ylabel("TOA BRF")
        ax.legend(fontsize=8)
        z = [(a - b) / s if s > 0 else 0.0 for a, b, s in zip(y, y_ref, e)]
        bx.plot(x_ref, z, "o", ms=3, color="C0")
        bx.axhline(0, color="k", lw=0.8)
        for lim in (-2, 2):
            bx.axhline(lim, color="0.6", lw=0.6, ls="--")
        bx.set_ylim(-5, 5)
        bx.set_ylabel("(MC − DISORT)/σ")
        bx.set_xlabel("signed VZA [deg] (+ = Sun's side)")
        print(f"{name}: max |rel diff| {max(abs(a / b - 1) for a, b in zip(y, y_ref)):.2e}, "
              f"max |z| {max(abs(v) for v in z):.2f}")
    fig.suptitle(f"Principal-plane TOA BRF: simulate (forward walk, {spp:.0e} photons) vs DISORT", fontsize=10)
    fig.tight_layout()
    out = os.path.join(ROOT, "docs", "img", "validation_principal_plane.png")
    fig.savefig(out, dpi=90)
    print("wrote", out)


if __name__ == "__main__":
    main()
