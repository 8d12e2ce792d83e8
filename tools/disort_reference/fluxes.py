#!/usr/bin/env python3
"""Generate the DISORT hemispherical-flux references of the `distant_flux` measures (issue 17
item 5): upwelling, direct downwelling and diffuse downwelling flux at the top, the middle and
the bottom of one homogeneous layer.

Writes ``simulator/tests/data/disort/fluxes.csv`` with the columns
``case,tau,ssa,g,albedo,sza,level_tau,altitude_km,quantity,value``:

* cases ``A*``: the shared case A set (``shared/reference/caseA_disort_public.csv``): a
  conservative Rayleigh layer (tau 0.1, 0.5) over a Lambertian surface (0, 0.3), SZA 30 and 60;
* cases ``F*``: an absorbing Henyey-Greenstein layer (tau 1, omega 0.9, g 0.7) over a
  Lambertian surface of reflectance 0.2, SZA 30 and 60 (anisotropic and absorbing, so the
  diffuse fluxes depend on the phase function's forward peak).

The layer spans 0-100 km in the simulator's homogeneous atmosphere, so ``level_tau`` 0, tau/2
and tau are the altitudes 100, 50 and 0 km.  ``quantity``: ``up`` (upwelling), ``down_direct``
(the attenuated solar beam on a horizontal plane) and ``down_diffuse`` (scattered downwelling),
each divided by E0 cos SZA (E0 = 1 normal to the beam): the simulator's `albedo` column of a
`distant_flux` measure.

Solver: nanodisort (cdisort) with 128 streams, fluxes only, delta-M off (moment nstr is zero);
checked against 96 streams (the difference is printed and asserted below 1e-6).  Checks:
direct flux = exp(-tau/mu0) (closed form) and energy conservation of the conservative cases
(absorbed = 0: TOA net flux equals the surface's absorbed flux).
It also writes ``simulator/tests/data/disort/hdrf.csv``
(``case,tau,sza,rho_0,k,g,raa,vza,quantity,value``, quantity ``hdrf``): the surface's
hemispherical-directional reflectance factor pi L_up(BOA, v) / E_down(BOA) of the RPV cases E1
and E2 of ``generate.py`` (Rayleigh tau 0.2, SZA 30) from DisORT++ (96 streams, checked against
80) with its directly reflected beam replaced by the exact RPV BRDF, as ``generate.py`` does at
the top of the atmosphere (at the surface the beam is attenuated once, by exp(-tau/mu0)).

And ``simulator/tests/data/disort/mirror.csv`` (``case,tau,sza,raa,vza,quantity,value``,
quantity ``brf``): the TOA BRF of a conservative Rayleigh layer of optical thickness tau over a
perfect specular reflector (R = 1), by the method of images: unfolding the mirror makes a
symmetric slab of thickness 2 tau over a black surface, whose reflected radiance at its top plus
transmitted diffuse radiance at its bottom (in the mirrored direction) is the upwelling radiance
of the real layer; views away from the specular direction of the Sun (whose direct beam is a
delta). cdisort (nanodisort), 128 streams, checked against 96.

Run from the repository root with the venv of README.md: ``python tools/disort_reference/fluxes.py``.
"""
from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

import nanodisort as nd

from generate import rpv_brf, run_disortpp  # the case E tables' RPV formula and solver

HERE = Path(__file__).resolve().parent
REPO = HERE.parent.parent
OUT = REPO / "simulator" / "tests" / "data" / "disort" / "fluxes.csv"
OUT_HDRF = OUT.with_name("hdrf.csv")
HDRF_VZA = np.arange(0.0, 81.0, 10.0)
HDRF_RAA = (0.0, 90.0, 180.0)
HDRF_CASES = [("E1", 0.1, 0.543, -0.29), ("E2", 0.25, 1.2, 0.15)]  # generate.py's case E
NSTR = (128, 96)


def chi(g, n):
    if g is None:  # Rayleigh (no depolarization)
        c = np.zeros(n)
        c[0], c[2] = 1.0, 0.1
        return c
    return g ** np.arange(n, dtype=float)


def solve(tau, ssa, g, albedo, sza, levels, nstr):
    ds = nd.DisortState()
    ds.nstr, ds.nlyr, ds.nmom, ds.ntau = nstr, 1, nstr, len(levels)
    ds.numu, ds.nphi, ds.nphase = 0, 0, 0
    ds.usrtau = ds.lamber = ds.quiet = ds.onlyfl = True
    ds.usrang = ds.planck = ds.spher = False
    ds.intensity_correction = False
    ds.old_intensity_correction = True
    ds.allocate()
    ds.dtauc = np.array([tau])
    ds.ssalb = np.array([ssa])
    pm = np.zeros((nstr + 1, 1))
    pm[:nstr, 0] = chi(g, nstr)
    ds.pmom = pm
    ds.utau = np.asarray(levels, dtype=float)
    ds.fbeam, ds.umu0, ds.phi0, ds.fisot = 1.0, math.cos(math.radians(sza)), 0.0, 0.0
    ds.albedo = albedo
    ds.accur = 0.0
    ds.solve()
    return (np.array(ds.flup, dtype=float), np.array(ds.rfldir, dtype=float),
            np.array(ds.rfldn, dtype=float))


def main():
    cases = []
    rows = list(csv.DictReader(open(REPO.parent / "shared" / "reference" / "caseA_disort_public.csv")))
    seen = []
    for r in rows:
        k = (float(r["tau"]), float(r["albedo"]), float(r["sza"]))
        if k not in seen:
            seen.append(k)
    for i, (tau, alb, sza) in enumerate(seen):
        cases.append((f"A{i + 1}", tau, 1.0, None, alb, sza))
    for i, sza in enumerate((30.0, 60.0)):
        cases.append((f"F{i + 1}", 1.0, 0.9, 0.7, 0.2, sza))

    out = []
    worst_conv = worst_direct = worst_energy = 0.0
    for cid, tau, ssa, g, alb, sza in cases:
        mu0 = math.cos(math.radians(sza))
        levels = [0.0, tau / 2, tau]
        up, ddir, ddif = solve(tau, ssa, g, alb, sza, levels, NSTR[0])
        up2, ddir2, ddif2 = solve(tau, ssa, g, alb, sza, levels, NSTR[1])
        worst_conv = max(worst_conv, float(np.max(np.abs(np.r_[up - up2, ddif - ddif2]))))
        exact = mu0 * np.exp(-np.asarray(levels) / mu0)
        worst_direct = max(worst_direct, float(np.max(np.abs(ddir / exact - 1))))
        if ssa == 1.0:
            # No absorption in the layer: net flux is the same at every level.
            net = ddir + ddif - up
            worst_energy = max(worst_energy, float(np.max(np.abs(net - net[0]))))
        for lt, z, u, dd, df in zip(levels, (100.0, 50.0, 0.0), up, ddir, ddif):
            for q, v in (("up", u), ("down_direct", dd), ("down_diffuse", df)):
                out.append([cid, tau, ssa, "" if g is None else g, alb, sza, lt, z, q,
                            f"{v / mu0:.10e}"])
    print(f"[check] 128 vs 96 streams: max |diff| {worst_conv:.2e}")
    print(f"[check] direct flux vs exp(-tau/mu0): max rel diff {worst_direct:.2e}")
    print(f"[check] conservative cases, net flux constant with height: max |diff| {worst_energy:.2e}")
    assert worst_conv < 1e-6 and worst_direct < 1e-12 and worst_energy < 1e-9
    with open(OUT, "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(["case", "tau", "ssa", "g", "albedo", "sza", "level_tau", "altitude_km",
                    "quantity", "value"])
        w.writerows(out)
    print(f"wrote {OUT} ({len(out)} rows)")


def hdrf_case(tau, sza, rpv, nstr):
    """{(raa, vza): HDRF} at the surface."""
    mu0 = math.cos(math.radians(sza))
    umu = np.sort(np.cos(np.radians(HDRF_VZA)))
    vza_sorted = np.degrees(np.arccos(umu))
    phis = [180.0 - r for r in HDRF_RAA]
    r = run_disortpp([(tau, 1.0, chi(None, nstr))], sza, umu, phis, nstr, rpv=rpv)
    s = run_disortpp([(1e-12, 1.0, chi(None, nstr))], sza, umu, phis, nstr, rpv=rpv)
    fdn = r["rfldn_boa"]
    e_down = mu0 * math.exp(-tau / mu0) + fdn
    out = {}
    for j, raa in enumerate(HDRF_RAA):
        # DisORT++'s Fourier reconstruction of the directly reflected beam (a bare surface),
        # replaced by the exact BRDF; in pi L / mu0 units, attenuated once at the surface.
        s_v = np.pi * s["uu_toa"][:, j] / mu0
        exact = rpv_brf(rpv[0], rpv[1], rpv[2], rpv[0], sza, vza_sorted, raa)
        boa = np.pi * r["uu_boa"][:, j] / mu0 + (exact - s_v) * math.exp(-tau / mu0)
        for z, v in zip(vza_sorted, boa * mu0 / e_down):
            out[(raa, round(float(z), 6))] = float(v)
    return out


def main_hdrf():
    tau, sza = 0.2, 30.0
    node = np.min(np.abs(np.cos(np.radians(np.r_[HDRF_VZA, sza]))[:, None]
                         - (0.5 * (np.polynomial.legendre.leggauss(48)[0] + 1))[None, :]))
    assert node > 1e-4, node
    rows, worst = [], 0.0
    for cid, rho0, k, g in HDRF_CASES:
        a = hdrf_case(tau, sza, (rho0, k, g), 96)
        b = hdrf_case(tau, sza, (rho0, k, g), 80)
        worst = max(worst, max(abs(b[key] / a[key] - 1) for key in a))
        for (raa, vza), v in sorted(a.items()):
            rows.append([cid, tau, sza, rho0, k, g, raa, vza, "hdrf", f"{v:.10e}"])
    print(f"[check] HDRF 96 vs 80 streams: max rel diff {worst:.2e}")
    assert worst < 2e-4, worst
    with open(OUT_HDRF, "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(["case", "tau", "sza", "rho_0", "k", "g", "raa", "vza", "quantity", "value"])
        w.writerows(rows)
    print(f"wrote {OUT_HDRF} ({len(rows)} rows)")


def mirror_case(tau, sza, nstr):
    """{(raa, vza): BRF} over a perfect mirror (method of images: a 2 tau slab over black)."""
    mu0 = math.cos(math.radians(sza))
    mus = np.cos(np.radians(HDRF_VZA))
    umu = np.sort(np.r_[-mus, mus])
    phis = [180.0 - r for r in HDRF_RAA]
    ds = nd.DisortState()
    ds.nstr, ds.nlyr, ds.nmom, ds.ntau = nstr, 1, nstr, 2
    ds.numu, ds.nphi, ds.nphase = len(umu), len(phis), 0
    ds.usrtau = ds.usrang = ds.lamber = ds.quiet = True
    ds.onlyfl = ds.planck = ds.spher = False
    ds.intensity_correction = False
    ds.old_intensity_correction = True
    ds.allocate()
    ds.dtauc = np.array([2 * tau])
    ds.ssalb = np.array([1.0])
    pm = np.zeros((nstr + 1, 1))
    pm[:nstr, 0] = chi(None, nstr)
    ds.pmom = pm
    ds.utau = np.array([0.0, 2 * tau])
    ds.umu = umu
    ds.phi = np.asarray(phis, dtype=float)
    ds.fbeam, ds.umu0, ds.phi0, ds.fisot = 1.0, mu0, 0.0, 0.0
    ds.albedo = 0.0
    ds.accur = 0.0
    ds.solve()
    uu = np.array(ds.uu)  # [umu, utau, phi]
    out = {}
    for j, raa in enumerate(HDRF_RAA):
        for mu, vza in zip(mus, HDRF_VZA):
            up = uu[int(np.where(np.isclose(umu, mu))[0][0]), 0, j]
            down = uu[int(np.where(np.isclose(umu, -mu))[0][0]), 1, j]
            out[(raa, float(vza))] = math.pi * (up + down) / mu0
    return out


def main_mirror():
    rows, worst = [], 0.0
    for cid, tau, sza in (("M1", 0.25, 30.0), ("M2", 0.1, 60.0)):
        a = mirror_case(tau, sza, 128)
        b = mirror_case(tau, sza, 96)
        worst = max(worst, max(abs(b[k] / a[k] - 1) for k in a))
        for (raa, vza), v in sorted(a.items()):
            if raa == 180.0 and abs(vza - sza) < 1e-9:
                continue  # the Sun's specular direction
            rows.append([cid, tau, sza, raa, vza, "brf", f"{v:.10e}"])
    print(f"[check] mirror 128 vs 96 streams: max rel diff {worst:.2e}")
    assert worst < 1e-5, worst
    out = OUT.with_name("mirror.csv")
    with open(out, "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(["case", "tau", "sza", "raa", "vza", "quantity", "value"])
        w.writerows(rows)
    print(f"wrote {out} ({len(rows)} rows)")


if __name__ == "__main__":
    main()
    main_hdrf()
    main_mirror()
