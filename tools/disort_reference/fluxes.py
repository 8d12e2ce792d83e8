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
Run from the repository root with the venv of README.md: ``python tools/disort_reference/fluxes.py``.
"""
from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

import nanodisort as nd

HERE = Path(__file__).resolve().parent
REPO = HERE.parent.parent
OUT = REPO / "simulator" / "tests" / "data" / "disort" / "fluxes.csv"
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


if __name__ == "__main__":
    main()
