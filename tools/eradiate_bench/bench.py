#!/usr/bin/env python3
"""Speed benchmark of Eradiate (Mitsuba 3 kernel) on the reference 1D case.

Case: plane-parallel homogeneous atmosphere, Rayleigh phase function,
vertical optical thickness 0.5 (550 nm), single-scattering albedo 1,
TOA at 100 km, Lambertian surface (reflectance 0.3), directional
illumination SZA 30 deg / SAA 0 deg, TOA BRF in the principal plane at
view zeniths -85..85 step 5 (35 directions).

Sign convention of the printed output: positive view zenith = sensor on
the Sun's side (relative azimuth 0, backscattering side). This is also
Eradiate's convention for `MultiDistantMeasure.hplane(azimuth=<SAA>)`:
illumination and viewing azimuths both give the position of the
Sun / sensor, and negative zeniths are mapped to azimuth + 180 deg.

Run with the interpreter of the Eradiate virtual environment, e.g.
    /tmp/eradiate-venv/bin/python tools/eradiate_bench/bench.py --spp 1000000

See README.md next to this file.
"""

from __future__ import annotations

import argparse
import sys
import time

# Sets the offline environment Eradiate reads at import: import it first.
from common import (add_scheduling_args, brf_result, resolve_scheduling,
                    scheduling_kdict, signed_zeniths, start_kernel)

# Case definition -------------------------------------------------------------
TAU = 0.5  # vertical optical thickness at 550 nm
TOA_KM = 100.0  # top of atmosphere altitude
SIGMA_S_PER_KM = TAU / TOA_KM  # homogeneous => tau = sigma_t * H
SURFACE_REFLECTANCE = 0.3
SZA_DEG = 30.0
SAA_DEG = 0.0
WAVELENGTH_NM = 550.0
VZA_DEG = list(range(-85, 86, 5))  # 35 directions, signed (+ = Sun's side)

# DISORT exact TOA BRFs for this case (our convention: + = Sun's side).
DISORT_REF = {
    0: 0.380268,
    30: 0.416674,
    -30: 0.359197,
    60: 0.469859,
    -60: 0.385468,
    75: 0.514644,
    -75: 0.446219,
}


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--spp", type=int, default=1000,
                   help="samples per direction (per mdistant pixel) per run")
    p.add_argument("--repeats", type=int, default=1,
                   help="number of independent runs (different seeds); with "
                        "N>=2 the mean and standard error of the mean across "
                        "repeats are reported as well")
    p.add_argument("--seed", type=int, default=0,
                   help="root seed; run i uses a seed derived from it")
    add_scheduling_args(p)
    p.add_argument("--integrator", default="volpath",
                   choices=["volpath", "eovolpath", "volpathmis"],
                   help="Eradiate integrator (Eradiate's own default for a "
                        "homogeneous atmosphere is volpath)")
    p.add_argument("--sign-flip", action="store_true",
                   help="debug: label output with the opposite zenith sign")
    return p.parse_args(argv)


def build_experiment(spp: int, integrator: str, moment: bool,
                     block_size: int = 0, passes: int = 1):
    import numpy as np
    import eradiate
    from eradiate.experiments import AtmosphereExperiment
    from eradiate.scenes.atmosphere import HomogeneousAtmosphere
    from eradiate.scenes.bsdfs import LambertianBSDF
    from eradiate.scenes.illumination import DirectionalIllumination
    from eradiate.scenes.measure import MultiDistantMeasure
    from eradiate.scenes.phase import RayleighPhaseFunction
    from eradiate.units import unit_registry as ureg

    measure = MultiDistantMeasure.hplane(
        id="toa_brf",
        zeniths=np.array(VZA_DEG, dtype=float) * ureg.deg,
        azimuth=SAA_DEG * ureg.deg,
        srf={"type": "delta", "wavelengths": WAVELENGTH_NM * ureg.nm},
        spp=spp,
    )
    exp = AtmosphereExperiment(
        geometry={"type": "plane_parallel", "toa_altitude": TOA_KM * ureg.km},
        atmosphere=HomogeneousAtmosphere(
            # Scalars become UniformSpectrum (wavelength-independent): no
            # data needed (the default sigma_s is the US76 air value).
            sigma_s=SIGMA_S_PER_KM / ureg.km,
            sigma_a=0.0 / ureg.km,
            phase=RayleighPhaseFunction(),  # depolarization 0 => 3/4(1+mu^2)
        ),
        surface={"type": "lambertian", "reflectance": SURFACE_REFLECTANCE},
        illumination=DirectionalIllumination(
            zenith=SZA_DEG * ureg.deg,
            azimuth=SAA_DEG * ureg.deg,
            # Uniform irradiance spectrum, 1 W/m2/nm (default would be a solar
            # spectrum data set); the BRF does not depend on its value.
            irradiance=1.0 * ureg("W/m^2/nm"),
        ),
        measures=[measure],
        integrator={"type": integrator, "moment": moment},
    )
    exp.kdict = scheduling_kdict(spp, block_size, passes)
    assert isinstance(exp.surface.bsdf, LambertianBSDF)
    return exp


def main(argv=None) -> int:
    args = parse_args(argv)
    if args.repeats < 1:
        print("--repeats must be >= 1", file=sys.stderr)
        return 2
    error = resolve_scheduling(args)
    if error:
        print(error, file=sys.stderr)
        return 2

    t_import0 = time.perf_counter()
    import numpy as np
    import drjit as dr
    import mitsuba as mi
    import eradiate
    from eradiate.rng import SeedState

    eradiate.set_mode("mono_double")
    t_import = time.perf_counter() - t_import0

    start_kernel(args, dr, mi, eradiate)
    print(f"case: homogeneous Rayleigh tau={TAU} ssa=1 TOA={TOA_KM} km, "
          f"Lambertian {SURFACE_REFLECTANCE}, SZA={SZA_DEG} SAA={SAA_DEG}, "
          f"{len(VZA_DEG)} directions, spp={args.spp}/direction, "
          f"repeats={args.repeats}, seed={args.seed}")

    # Setup: experiment construction + kernel scene loading (not timed as run)
    t0 = time.perf_counter()
    exp = build_experiment(args.spp, args.integrator, not args.no_moment,
                           args.block_size, args.passes)
    exp.init()
    t_setup = time.perf_counter() - t0

    seed_state = SeedState(args.seed)
    brfs, stderrs, run_walls, run_cpus, post_walls = [], [], [], [], []
    for _ in range(args.repeats):
        w0, c0 = time.perf_counter(), time.process_time()
        exp.process(spp=args.spp, seed_state=seed_state)  # Mitsuba render
        run_walls.append(time.perf_counter() - w0)
        run_cpus.append(time.process_time() - c0)

        w0 = time.perf_counter()
        exp.postprocess()
        ds = exp.results["toa_brf"]
        post_walls.append(time.perf_counter() - w0)

        vza, vaa, brf, se = brf_result(ds)
        brfs.append(brf)
        if se is not None:
            stderrs.append(se)

    # Map Eradiate angles to our signed-zenith convention (+ = Sun's side).
    # Eradiate: vaa == SAA for positive input zeniths, SAA+180 for negative.
    signed = signed_zeniths(vza, vaa, SAA_DEG)
    if args.sign_flip:
        signed = -signed
    order = np.argsort(signed)
    signed = signed[order]
    brfs = np.array(brfs)[:, order]
    stderrs = np.array(stderrs)[:, order] if stderrs else None

    n = args.repeats
    mean = brfs.mean(axis=0)
    sem_rep = brfs.std(axis=0, ddof=1) / np.sqrt(n) if n >= 2 else None
    # in-run estimate of the stderr of the mean over all repeats
    sem_mom = (np.sqrt((stderrs ** 2).sum(axis=0)) / n) if stderrs is not None else None

    print()
    print(f"import time      : {t_import:.3f} s")
    print(f"setup time       : {t_setup:.3f} s (experiment build + kernel scene load)")
    print(f"run wall time    : {sum(run_walls):.3f} s total over {n} run(s); "
          f"per run: {', '.join(f'{w:.3f}' for w in run_walls)} s")
    print(f"run CPU time     : {sum(run_cpus):.3f} s "
          f"(CPU/wall = {sum(run_cpus) / max(sum(run_walls), 1e-12):.2f})")
    print(f"postprocess time : {sum(post_walls):.3f} s total")
    tot_samples = args.spp * len(VZA_DEG) * n
    print(f"throughput       : {tot_samples / sum(run_walls):.4g} samples/s "
          f"({tot_samples} samples)")

    print()
    hdr = f"{'vza':>5} {'BRF':>10}"
    if sem_mom is not None:
        hdr += f" {'stderr(m2)':>11}"
    if sem_rep is not None:
        hdr += f" {'stderr(rep)':>11}"
    hdr += f" {'DISORT':>9} {'diff/se':>8}"
    print(hdr)
    for i, z in enumerate(signed):
        zi = int(round(z))
        line = f"{zi:+5d} {mean[i]:10.6f}"
        if sem_mom is not None:
            line += f" {sem_mom[i]:11.3e}"
        if sem_rep is not None:
            line += f" {sem_rep[i]:11.3e}"
        if zi in DISORT_REF:
            # prefer the in-run (2nd moment) stderr: it is far less noisy
            # than a stderr estimated from a handful of repeats
            se = sem_mom[i] if sem_mom is not None else (
                sem_rep[i] if sem_rep is not None else np.nan)
            line += f" {DISORT_REF[zi]:9.6f} {(mean[i] - DISORT_REF[zi]) / se:8.2f}"
        print(line)

    print()
    for name, sem in (("2nd moment", sem_mom), ("across repeats", sem_rep)):
        if sem is None:
            continue
        rel = sem / mean
        print(f"relative stderr ({name}): median {np.median(rel):.3e}, "
              f"max {np.max(rel):.3e}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
