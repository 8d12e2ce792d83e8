#!/usr/bin/env python3
"""Write a scalar experiment TOML of the ARTDECO O2 A-band case (shared data `artdeco_o2a/`,
MANIFEST §4; the layers of `simulator/tests/artdeco_o2a.rs`): Rayleigh (depolarization 0) + O2
in the files' 49 layers (0–120 km), black surface, SZA 30°, one TOA direction (VZA 20°, VAA 180°),
backward walks. Used by BENCHMARKS.md (spectral ALIS).

    python3 tools/artdeco_o2a/experiment.py [--first 0] [--last 1089] [--alis-group N]
        [--spp 100000000] [--target 1e-3] [--data ../shared/data/artdeco_o2a] > exp.toml
"""
import argparse
import os
import sys


def read_cumulative(path):
    lines = [l for l in open(path) if l.strip() and not l.lstrip().startswith("#")]
    nwl, nalt = int(float(lines[0].split()[0])), int(float(lines[1].split()[0]))
    wavelengths = [float(x) for x in lines[2].split()]
    assert len(wavelengths) == nwl
    altitudes, cum = [], []
    for l in lines[3 : 3 + nalt]:
        row = [float(x) for x in l.split()]
        altitudes.append(row[0])
        cum.append(row[1:])
    return wavelengths, altitudes, cum


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    p = argparse.ArgumentParser()
    p.add_argument("--data", default=os.path.join(here, "../../../shared/data/artdeco_o2a"))
    p.add_argument("--first", type=int, default=0)
    p.add_argument("--last", type=int, default=1089, help="one past the last wavelength index")
    p.add_argument("--alis-group", type=int, default=0, help="0: independent walks")
    p.add_argument("--spp", type=int, default=100_000_000)
    p.add_argument("--target", type=float, default=1e-3)
    p.add_argument("--seed", type=int, default=5)
    a = p.parse_args()
    wl, alt, gas = read_cumulative(os.path.join(a.data, "cTauGas_ray_O2.dat"))
    _, alt_r, ray = read_cumulative(os.path.join(a.data, "cTauRay_ray_O2.dat"))
    assert alt == alt_r
    idx = range(a.first, a.last)
    layer = lambda c, l, k: max(c[l + 1][k] - c[l][k], 0.0)
    fmt = lambda v: ", ".join(repr(x) for x in v)
    out = [
        f"seed = {a.seed}",
        "polarized = false",
        "[spectral]",
        f"wavelengths = [{fmt(wl[k] for k in idx)}]",
        "[geometry]",
        'type = "plane_parallel"',
        "toa_altitude = 120.0",
        "[atmosphere]",
        'type = "layered"',
    ]
    for l in range(len(alt) - 1):
        out += [
            "[[atmosphere.layers]]",
            f"bottom = {alt[l + 1]!r}",
            f"top = {alt[l]!r}",
            'phase = { type = "rayleigh", depolarization = 0.0 }',
            f"tau_sca = [{fmt(layer(ray, l, k) for k in idx)}]",
            f"tau_abs = [{fmt(layer(gas, l, k) for k in idx)}]",
        ]
    out += [
        "[surface]",
        'type = "lambertian"',
        "reflectance = 0.0",
        "[illumination]",
        'type = "directional"',
        "zenith = 30.0",
        "azimuth = 0.0",
        "[integrator]",
        'type = "backward"',
    ]
    if a.alis_group > 0:
        out += ['spectral_walk = "alis"', f"alis_group = {a.alis_group}"]
    out += [
        "[[measures]]",
        'id = "toa"',
        'type = "mdistant"',
        'construct = "directions"',
        "zeniths = [20.0]",
        "azimuths = [180.0]",
        f"spp = {a.spp}",
    ]
    if a.target > 0:
        out.append(f"target_rel_stderr = {a.target!r}")
    sys.stdout.write("\n".join(out) + "\n")


if __name__ == "__main__":
    main()
