#!/usr/bin/env python3
"""Generate the thermal-emission DISORT references (issue 16) for the Monte Carlo tests.

Writes ``simulator/tests/data/disort/thermal.csv`` and ``thermal_cases.toml``.
See README.md next to this file ("Thermal cases") for the conventions and how to rerun.

Solver: nanodisort (cdisort) with ``planck = True``.  cdisort's thermal source is the Planck
function integrated over a wavenumber interval [wvnmlo, wvnmhi] (cm^-1), linear in optical
depth inside each layer between its values at the level temperatures; the bottom boundary
emits (1 - albedo) B(btemp) for a Lambertian surface.  We run a narrow interval (0.01 cm^-1)
about 1000 cm^-1 (10 um) and convert to spectral radiance per nm by the factor
f = B_lambda(T_s) / PLKAVG(T_s), computed at each case's surface temperature from a cdisort run
of a bare black surface.  PLKAVG's own accuracy makes f vary by 1.8e-5 over 200-330 K (checked
below), i.e. < 0.002 K in brightness temperature.  The solar beam, when there is one, enters
cdisort as fbeam = E0 / f so that the whole solution scales by f.

Every check asserts; the script stops if one fails.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

import nanodisort as nd

HERE = Path(__file__).resolve().parent
REPO = HERE.parent.parent
OUT_DIR = REPO / "simulator" / "tests" / "data" / "disort"

# CODATA 2018 (exact): the same constants as engine/src/sources/planck.rs.
H, C, KB = 6.62607015e-34, 299792458.0, 1.380649e-23
WL_NM = 10000.0
NU = 1e7 / WL_NM  # cm^-1
DNU = 0.01
VZA = [0.0, 20.0, 40.0, 60.0, 75.0]
RAAS = [0.0, 90.0, 180.0]
NSTR = (128, 96)  # table, convergence check


def planck(t, wl_nm=WL_NM):
    l = wl_nm * 1e-9
    return 2 * H * C * C / l ** 5 / math.expm1(H * C / (l * KB * t)) * 1e-9


def brightness_temperature(rad, wl_nm=WL_NM):
    l = wl_nm * 1e-9
    return H * C / (l * KB) / math.log1p(2 * H * C * C / (l ** 5 * rad * 1e9))


def chi_hg(g, n):
    return g ** np.arange(n, dtype=float)


def chi_rayleigh(n):
    c = np.zeros(n)
    c[0] = 1.0
    c[2] = 0.1
    return c


def chi(phase, n):
    if phase["type"] == "hg":
        return chi_hg(phase["g"], n)
    if phase["type"] == "rayleigh":
        return chi_rayleigh(n)
    raise ValueError(phase)


def solve(layers_top_down, temper, albedo, btemp, sza, fbeam, umu, phis, nstr, ttemp=0.0,
          temis=0.0):
    """layers: (dtau, ssa, chi) top to bottom; temper: level temperatures top to bottom."""
    nl = len(layers_top_down)
    ds = nd.DisortState()
    ds.nstr, ds.nlyr, ds.nmom, ds.ntau = nstr, nl, nstr, 2
    ds.numu, ds.nphi, ds.nphase = len(umu), len(phis), 0
    ds.usrtau = ds.usrang = ds.lamber = ds.quiet = True
    ds.onlyfl = ds.spher = False
    ds.planck = True
    ds.intensity_correction = False
    ds.old_intensity_correction = True
    ds.allocate()
    ds.dtauc = np.array([l[0] for l in layers_top_down], dtype=float)
    ds.ssalb = np.array([l[1] for l in layers_top_down], dtype=float)
    pm = np.zeros((nstr + 1, nl))
    for i, l in enumerate(layers_top_down):
        c = np.asarray(l[2], dtype=float)[:nstr]
        pm[:len(c), i] = c
    ds.pmom = pm
    ds.utau = np.array([0.0, float(sum(l[0] for l in layers_top_down))])
    ds.umu = np.asarray(umu, dtype=float)
    ds.phi = np.asarray(phis, dtype=float)
    ds.fbeam = fbeam
    ds.umu0 = math.cos(math.radians(sza)) if sza is not None else 1.0
    ds.phi0, ds.fisot = 0.0, 0.0
    ds.albedo = albedo
    ds.btemp, ds.ttemp, ds.temis = btemp, ttemp, temis
    ds.temper = np.asarray(temper, dtype=float)
    ds.wvnmlo, ds.wvnmhi = NU - DNU / 2, NU + DNU / 2
    ds.accur = 0.0
    ds.solve()
    return np.array(ds.uu[:, 0, :])


def plkavg(t):
    """cdisort's band Planck value at t: a bare black surface seen from above."""
    uu = solve([(1e-10, 0.0, chi_rayleigh(16))], [t, t], 0.0, t, None, 0.0, [1.0], [0.0], 16)
    return float(uu[0, 0])


def factor(t):
    return planck(t) / plkavg(t)


def check_factor():
    fs = [factor(t) for t in (200.0, 250.0, 300.0, 330.0)]
    spread = max(fs) / min(fs) - 1
    print(f"[check] B_lambda / PLKAVG over 200-330 K: spread {spread:.2e} (PLKAVG accuracy)")
    assert spread < 3e-5, spread
    return spread


def check_black_body():
    """An isothermal enclosure at T (black top boundary at T as well): the radiance is B(T) in
    every direction, whatever the scattering and the surface (equilibrium, Kirchhoff); and
    tau -> inf gives B(T_layer) for any surface."""
    t = 270.0
    uu = solve([(2.0, 0.6, chi_hg(0.7, 32))], [t, t], 0.3, t, None, 0.0, [0.2, 0.6, 1.0],
               [0.0], 32, ttemp=t, temis=1.0)
    err = float(np.max(np.abs(uu * factor(t) / planck(t) - 1)))
    print(f"[check] isothermal enclosure (tau 2, ssa 0.6, albedo 0.3, all 270 K): "
          f"max |L/B - 1| = {err:.1e}")
    assert err < 1e-5, err
    uu = solve([(60.0, 0.0, chi_rayleigh(16))], [230.0, 230.0], 0.0, 320.0, None, 0.0,
               [0.2, 0.6, 1.0], [0.0], 16)
    err = float(np.max(np.abs(uu * factor(230.0) / planck(230.0) - 1)))
    print(f"[check] optically thick (tau 60) 230 K layer over a 320 K surface: "
          f"max |L/B(230) - 1| = {err:.1e}")
    assert err < 1e-5, err


def check_closed_form():
    """Non-scattering isothermal layer over a black surface: B(1 - e^{-tau/mu}) + B_s e^{-tau/mu}."""
    tau, t, ts = 0.8, 240.0, 300.0
    mus = np.array([0.3, 0.6, 1.0])
    uu = solve([(tau, 0.0, chi_rayleigh(16))], [t, t], 0.0, ts, None, 0.0, mus, [0.0], 16)
    f = factor(ts)
    want = planck(t) * (1 - np.exp(-tau / mus)) + planck(ts) * np.exp(-tau / mus)
    err = float(np.max(np.abs(uu[:, 0] * f / want - 1)))
    print(f"[check] non-scattering isothermal layer, black surface: max rel diff to the closed "
          f"form {err:.1e}")
    assert err < 3e-5, err


def layer(bottom, top, tau, ssa, phase, t_bottom, t_top):
    return dict(bottom=bottom, top=top, tau_sca=round(tau * ssa, 15),
                tau_abs=round(tau * (1 - ssa), 15), phase=phase, temperature_bottom=t_bottom,
                temperature_top=t_top)


def build_cases():
    hg = lambda g: {"type": "hg", "g": g}
    ray = {"type": "rayleigh"}
    return [
        # isothermal, non-scattering, black surface, no Sun
        dict(id="T1", sza=None, irradiance=None,
             surface=dict(reflectance=0.0, temperature=300.0),
             layers=[layer(0.0, 100.0, 1.0, 0.0, ray, 250.0, 250.0)]),
        # isothermal, scattering (HG 0.7), emissivity 0.9, no Sun
        dict(id="T2", sza=None, irradiance=None,
             surface=dict(reflectance=0.1, temperature=295.0),
             layers=[layer(0.0, 100.0, 1.0, 0.5, hg(0.7), 260.0, 260.0)]),
        # gradient, non-scattering, emissivity 0.7, no Sun
        dict(id="T3", sza=None, irradiance=None,
             surface=dict(reflectance=0.3, temperature=300.0),
             layers=[layer(0.0, 100.0, 2.0, 0.0, ray, 290.0, 220.0)]),
        # gradient, scattering (Rayleigh), emissivity 0.95, Sun at 30 deg
        dict(id="T4", sza=30.0, irradiance=0.02,
             surface=dict(reflectance=0.05, temperature=290.0),
             layers=[layer(0.0, 100.0, 1.5, 0.8, ray, 280.0, 230.0)]),
        # isothermal, scattering (HG 0.5), emissivity 0.9, Sun at 40 deg
        dict(id="T5", sza=40.0, irradiance=0.03,
             surface=dict(reflectance=0.1, temperature=300.0),
             layers=[layer(0.0, 100.0, 0.5, 0.9, hg(0.5), 270.0, 270.0)]),
        # two layers with gradients (continuous at 2 km), scattering and absorbing,
        # emissivity 0.7, Sun at 50 deg
        dict(id="T6", sza=50.0, irradiance=0.05,
             surface=dict(reflectance=0.3, temperature=295.0),
             layers=[layer(0.0, 2.0, 0.6, 0.3, hg(0.6), 288.0, 275.0),
                     layer(2.0, 100.0, 0.4, 0.7, ray, 275.0, 225.0)]),
    ]


def solve_case(case, nstr):
    lay = list(reversed(case["layers"]))  # top to bottom
    d_lay = [(l["tau_sca"] + l["tau_abs"],
              l["tau_sca"] / (l["tau_sca"] + l["tau_abs"]), chi(l["phase"], nstr)) for l in lay]
    temper = [lay[0]["temperature_top"]] + [l["temperature_bottom"] for l in lay]
    for upper, lower in zip(lay, lay[1:]):
        assert upper["temperature_bottom"] == lower["temperature_top"]  # cdisort: levels
    ts = case["surface"]["temperature"]
    f = factor(ts)
    fbeam = 0.0 if case["irradiance"] is None else case["irradiance"] / f
    mu = np.cos(np.radians(VZA))
    order = np.argsort(mu)
    uu = solve(d_lay, temper, case["surface"]["reflectance"], ts, case["sza"], fbeam,
               mu[order], [180.0 - r for r in RAAS], nstr)
    out = {}
    for j, raa in enumerate(RAAS):
        v = np.empty_like(mu)
        v[order] = uu[:, j] * f
        for vza, val in zip(VZA, v):
            out[(vza, raa)] = float(val)
    return out


def toml_value(v):
    if isinstance(v, str):
        return f'"{v}"'
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{k} = {toml_value(x)}" for k, x in v.items()) + " }"
    return repr(float(v))


def main():
    check_factor()
    check_black_body()
    check_closed_form()
    cases = build_cases()
    rows = []
    for c in cases:
        a, b = solve_case(c, NSTR[0]), solve_case(c, NSTR[1])
        conv = max(abs(b[k] / a[k] - 1) for k in a)
        print(f"[case] {c['id']}: nstr {NSTR[0]} vs {NSTR[1]}: max rel change {conv:.1e}")
        assert conv < 1e-5, (c["id"], conv)
        for (vza, raa), v in a.items():
            rows.append((c["id"], vza, raa, v, brightness_temperature(v)))
    OUT_DIR.mkdir(parents=True, exist_ok=True)
    with open(OUT_DIR / "thermal.csv", "w") as f:
        f.write("case,vza,raa,radiance,brightness_temperature\n")
        for r in rows:
            f.write(f"{r[0]},{r[1]!r},{r[2]!r},{r[3]:.9e},{r[4]:.6f}\n")
    lines = ["# Thermal-emission DISORT reference cases (generated by",
             "# tools/disort_reference/thermal.py; do not edit by hand). Plane-parallel,",
             f"# monochromatic at {WL_NM} nm, TOA upwelling radiance in W m-2 sr-1 nm-1",
             f"# (thermal.csv), cdisort {nd.__version__} via nanodisort with planck = true,",
             f"# nstr = {NSTR[0]} (checked against {NSTR[1]}), delta-M off. Layers bottom to top,",
             "# altitudes in km; temperatures in K; irradiance normal to the beam in",
             "# W m-2 nm-1, Sun azimuth 0 (raa = view azimuth).", ""]
    for c in cases:
        lines.append("[[case]]")
        lines.append(f'id = "{c["id"]}"')
        if c["sza"] is not None:
            lines.append(f"sza = {toml_value(c['sza'])}")
            lines.append(f"irradiance = {toml_value(c['irradiance'])}")
        lines.append("[case.surface]")
        lines.append('type = "lambertian"')
        for k, v in c["surface"].items():
            lines.append(f"{k} = {toml_value(v)}")
        for l in c["layers"]:
            lines.append("[[case.layers]]")
            for k in ("bottom", "top", "tau_sca", "tau_abs", "temperature_bottom",
                      "temperature_top"):
                lines.append(f"{k} = {toml_value(l[k])}")
            lines.append(f"phase = {toml_value(l['phase'])}")
        lines.append("")
    (OUT_DIR / "thermal_cases.toml").write_text("\n".join(lines))
    print(f"[done] wrote {len(rows)} rows to {OUT_DIR}")


if __name__ == "__main__":
    sys.exit(main())
