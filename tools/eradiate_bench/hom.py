#!/usr/bin/env python3
"""Peer benchmark: Eradiate 1.2 on the RAMI-like HOM discrete canopy.

Scene (as in examples/canopy/hom.toml and shared/data/canopy/MANIFEST.md):
one 10 m x 10 m x 2 m unit cell of 9549 bi-Lambertian discs (LAI 3, leaf
radius 0.1 m, rho 0.0546, tau 0.0149), padded to 5 x 5 copies (padding 2,
a 50 m x 50 m patch), over a 50 m x 50 m Lambertian soil square (0.127) at
z = 0; no atmosphere; 550 nm; directional Sun at zenith 20 deg; BRF in the
principal plane at 35 view zeniths -85..85 step 5, averaged over the top of
the central cell (x, y in [-5, 5] m, z = 2 m).

By default the leaves are read from the shared leaf file
shared/data/canopy/hom/hom_leaves.txt (columns x y z nx ny nz r), i.e. the
exact same discs as our simulator uses. `--leaves generator` uses Eradiate's
own `DiscreteCanopy.homogeneous` generator with the same parameters instead.

Angle convention of the printed table and the CSV: OUR signed view zenith
(examples/canopy/hom.toml): negative = on the Sun's side, hot spot at -20.
Eradiate (azimuth counter-clockwise from +X, like the manifest) gets the Sun
at azimuth 0 and `MultiDistantMeasure.hplane(azimuth=180, zeniths=ours)`:
positive zeniths lie in the half-plane at azimuth 180 (away from the Sun),
negative ones are mapped to azimuth 0 (the Sun's side), so the signed zeniths
are passed through unchanged. The sign is re-derived from the returned vaa.

Run with the interpreter of the Eradiate virtual environment, e.g.
    /tmp/eradiate-venv/bin/python tools/eradiate_bench/hom.py --spp 1000

See README.md next to this file.
"""

from __future__ import annotations

import argparse
import csv
import sys
import time
from pathlib import Path

# Sets the offline environment Eradiate reads at import: import it first.
from common import (add_scheduling_args, brf_result, resolve_scheduling,
                    scheduling_kdict, signed_zeniths, start_kernel)

REPO = Path(__file__).resolve().parents[2]
# shared/ sits next to the checkout (hom.toml refers to ../../../shared/...)
SHARED_CANOPY = REPO.parent / "shared" / "data" / "canopy" / "hom"

# Case definition -------------------------------------------------------------
CELL_XY_M = 10.0  # unit cell horizontal size
CELL_Z_M = 2.0  # unit cell height (canopy top)
LAI = 3.0
LEAF_RADIUS_M = 0.1
LEAF_RHO = 0.0546
LEAF_TAU = 0.0149
SOIL_RHO = 0.127
PADDING = 2  # 5 x 5 copies of the unit cell
SZA_DEG = 20.0
SAA_DEG = 0.0  # Eradiate / manifest convention (ccw from +X); ours = 90 deg
VIEW_HPLANE_AZ_DEG = 180.0  # half-plane of positive zeniths (ours: 270 deg)
WAVELENGTH_NM = 550.0
VZA_OURS = list(range(-85, 86, 5))  # 35 directions, signed (- = Sun's side)
# Goel-Strebel parameters stated in the header of hom_leaves.txt (they are
# also Eradiate's generator defaults); only used by --leaves generator.
LAD_MU, LAD_NU = 1.066, 1.853


def parse_args(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--spp", type=int, default=1000,
                   help="samples per direction (per mdistant pixel)")
    p.add_argument("--seed", type=int, default=0,
                   help="root seed (eradiate.rng.SeedState)")
    p.add_argument("--csv", type=Path, default=None,
                   help="write per-direction vza_ours,brf,brf_stderr here")
    p.add_argument("--leaves", choices=["file", "generator"], default="file",
                   help="'file': the shared leaf file (default, identical "
                        "discs to our simulator); 'generator': Eradiate's "
                        "DiscreteCanopy.homogeneous (LAI 3, r 0.1 m, "
                        "10x10x2 m, Goel-Strebel mu/nu, seed 12345)")
    p.add_argument("--leaf-file", type=Path,
                   default=SHARED_CANOPY / "hom_leaves.txt",
                   help="leaf file, columns x y z nx ny nz r (metres)")
    p.add_argument("--offsets-file", type=Path,
                   default=SHARED_CANOPY / "hom_cell_offsets.txt",
                   help="our 25 cell offsets; only used to check that "
                        "Eradiate's padding=2 produces the same copies")
    p.add_argument("--ref", type=Path,
                   default=REPO / "validation" / "canopy" / "hom_results.csv",
                   help="our simulator's results (principal_plane rows) for "
                        "the z-score column; missing file = no comparison")
    p.add_argument("--integrator", default="path",
                   choices=["path", "volpath"],
                   help="Eradiate integrator (no participating medium here, "
                        "so 'path' suffices; CanopyExperiment's own default "
                        "is volpath)")
    add_scheduling_args(p)
    return p.parse_args(argv)


def load_leaf_file(path: Path):
    """Read x y z nx ny nz r rows ('#' comments) -> positions, normals, radii."""
    import numpy as np

    a = np.loadtxt(path, comments="#", ndmin=2)
    if a.shape[1] != 7:
        raise ValueError(f"{path}: expected 7 columns x y z nx ny nz r, "
                         f"got {a.shape[1]}")
    pos, nrm, rad = a[:, 0:3], a[:, 3:6], a[:, 6]
    nrm = nrm / np.linalg.norm(nrm, axis=1, keepdims=True)  # file has 9 digits
    return pos, nrm, rad


def build_canopy(args):
    """Unpadded unit-cell DiscreteCanopy (padding is done by the experiment)."""
    import numpy as np
    from eradiate.scenes.biosphere import (DiscreteCanopy,
                                           InstancedCanopyElement, LeafCloud)
    from eradiate.units import unit_registry as ureg

    size = [CELL_XY_M, CELL_XY_M, CELL_Z_M] * ureg.m
    if args.leaves == "generator":
        # LeafCloud.cuboid via CuboidLeafCloudParams: n_leaves =
        # int(LAI (l_h / r)^2 / pi) = 9549, centres uniform in the cuboid
        return DiscreteCanopy.homogeneous(
            padding=0, id="hom", lai=LAI, leaf_radius=LEAF_RADIUS_M * ureg.m,
            l_horizontal=CELL_XY_M * ureg.m, l_vertical=CELL_Z_M * ureg.m,
            mu=LAD_MU, nu=LAD_NU, leaf_reflectance=LEAF_RHO,
            leaf_transmittance=LEAF_TAU)  # generator seed: default 12345

    # LeafCloud.from_file expects 'r x y z nx ny nz' without comment lines,
    # so build the LeafCloud from arrays (its default constructor) instead.
    pos, nrm, rad = load_leaf_file(args.leaf_file)
    cloud = LeafCloud(id="hom_leaf_cloud", leaf_positions=pos * ureg.m,
                      leaf_orientations=nrm, leaf_radii=rad * ureg.m,
                      leaf_reflectance=LEAF_RHO, leaf_transmittance=LEAF_TAU)
    return DiscreteCanopy(
        id="hom", size=size,
        instanced_canopy_elements=[InstancedCanopyElement(
            canopy_element=cloud, instance_positions=np.zeros((1, 3)) * ureg.m)])


def check_padding(canopy, offsets_file: Path) -> str:
    """Compare Eradiate's padding=2 copies with our offsets file."""
    import numpy as np

    padded = canopy.padded_copy(PADDING)
    got = padded.instanced_canopy_elements[0].instance_positions.m_as("m")
    if not offsets_file.is_file():
        return f"{len(got)} copies (offsets file not found, not compared)"
    want = np.loadtxt(offsets_file, comments="#", ndmin=2)
    key = lambda a: sorted(map(tuple, np.round(a, 6)))
    same = len(got) == len(want) and key(got) == key(want)
    return (f"{len(got)} copies, padded size "
            f"{' x '.join(f'{s:g}' for s in padded.size.m_as('m'))} m, "
            f"{'identical to' if same else 'DIFFERENT FROM'} {offsets_file.name}")


def build_experiment(canopy, spp: int, integrator: str, moment: bool,
                     block_size: int, passes: int):
    import numpy as np
    from eradiate.experiments import CanopyExperiment
    from eradiate.scenes.illumination import DirectionalIllumination
    from eradiate.scenes.measure import MultiDistantMeasure
    from eradiate.units import unit_registry as ureg

    half = 0.5 * CELL_XY_M
    measure = MultiDistantMeasure.hplane(
        id="principal_plane",
        # our signed zeniths as is: + -> azimuth 180 (away from the Sun),
        # - -> azimuth 0 (Sun's side, hot spot at -20)
        zeniths=np.array(VZA_OURS, dtype=float) * ureg.deg,
        azimuth=VIEW_HPLANE_AZ_DEG * ureg.deg,
        azimuth_convention="east_right",
        srf={"type": "delta", "wavelengths": WAVELENGTH_NM * ureg.nm},
        spp=spp,
        # top of the central (unpadded) cell, like our target_m /
        # target_height_m (also CanopyExperiment's default target)
        target={"type": "rectangle", "xmin": -half * ureg.m,
                "xmax": half * ureg.m, "ymin": -half * ureg.m,
                "ymax": half * ureg.m, "z": CELL_Z_M * ureg.m},
    )
    exp = CanopyExperiment(
        canopy=canopy,
        padding=PADDING,  # 5 x 5 copies; ground resized to 50 m x 50 m
        surface={"type": "lambertian", "reflectance": SOIL_RHO},
        illumination=DirectionalIllumination(
            zenith=SZA_DEG * ureg.deg,
            azimuth=SAA_DEG * ureg.deg,
            azimuth_convention="east_right",
            # uniform 1 W/m2/nm instead of the solar-spectrum data set
            irradiance=1.0 * ureg("W/m^2/nm"),
        ),
        measures=[measure],
        integrator={"type": integrator, "moment": moment},
    )
    exp.kdict = scheduling_kdict(spp, block_size, passes)
    return exp


def load_ref(path: Path):
    """Our principal-plane BRFs keyed by OUR signed vza (vaa 90 = Sun side)."""
    if not path or not path.is_file():
        return {}
    ref = {}
    with open(path, newline="") as f:
        for row in csv.DictReader(f):
            if row.get("measure") != "principal_plane":
                continue
            vza, vaa = float(row["vza"]), float(row["vaa"]) % 360.0
            # our azimuths: clockwise from North; Sun at 90 -> negative vza
            signed = -vza if abs(vaa - 90.0) < 1e-6 else vza
            ref[int(round(signed))] = (float(row["brf"]),
                                       float(row["brf_stderr"]))
    return ref


def main(argv=None) -> int:
    args = parse_args(argv)
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
    # Eradiate loads its submodules lazily: import the ones used below now so
    # that their import cost is counted as import time, not setup time.
    import eradiate.experiments  # noqa: F401
    import eradiate.scenes.biosphere  # noqa: F401
    import eradiate.scenes.illumination  # noqa: F401
    import eradiate.scenes.measure  # noqa: F401
    from eradiate.experiments import CanopyExperiment  # noqa: F401

    eradiate.set_mode("mono_double")
    t_import = time.perf_counter() - t_import0

    start_kernel(args, dr, mi, eradiate)
    moment = not args.no_moment

    # Setup 1: canopy (leaf file read or Eradiate generator)
    t0 = time.perf_counter()
    canopy = build_canopy(args)
    t_leaves = time.perf_counter() - t0
    cloud = canopy.instanced_canopy_elements[0].canopy_element
    n_leaves = cloud.n_leaves()
    lai = float(cloud.surface_area().m_as("m^2")) / CELL_XY_M ** 2
    src = (str(args.leaf_file) if args.leaves == "file"
           else "DiscreteCanopy.homogeneous generator (seed 12345)")
    print(f"case: HOM cell {CELL_XY_M:g}x{CELL_XY_M:g}x{CELL_Z_M:g} m, "
          f"{n_leaves} discs (LAI {lai:.4f}) from {src}; rho={LEAF_RHO} "
          f"tau={LEAF_TAU}; soil {SOIL_RHO}; padding {PADDING}: "
          f"{check_padding(canopy, args.offsets_file)}")
    print(f"      SZA={SZA_DEG:g} (Eradiate SAA={SAA_DEG:g} ccw from +X), "
          f"{len(VZA_OURS)} directions, {WAVELENGTH_NM:g} nm, "
          f"spp={args.spp}/direction, seed={args.seed}")

    # Setup 2: experiment object; setup 3: kernel dict + Mitsuba scene load
    t0 = time.perf_counter()
    exp = build_experiment(canopy, args.spp, args.integrator, moment,
                           args.block_size, args.passes)
    t_build = time.perf_counter() - t0
    t0 = time.perf_counter()
    exp.init()
    t_init = time.perf_counter() - t0
    t_setup = t_leaves + t_build + t_init

    w0, c0 = time.perf_counter(), time.process_time()
    exp.process(spp=args.spp, seed_state=SeedState(args.seed))
    t_run = time.perf_counter() - w0
    c_run = time.process_time() - c0

    w0 = time.perf_counter()
    exp.postprocess()
    ds = exp.results["principal_plane"]
    vza, vaa, brf, se = brf_result(ds)
    if se is None:
        se = np.full_like(brf, np.nan)
    t_post = time.perf_counter() - w0

    # Eradiate vaa (ccw from +X): 180 -> our positive zenith, 0 -> negative
    signed = signed_zeniths(vza, vaa, VIEW_HPLANE_AZ_DEG)
    order = np.argsort(signed)
    signed, brf, se = signed[order], brf[order], se[order]

    print()
    print(f"import time      : {t_import:.3f} s")
    print(f"setup time       : {t_setup:.3f} s (leaves {t_leaves:.3f} + "
          f"experiment build {t_build:.3f} + kernel dict & Mitsuba scene "
          f"load {t_init:.3f})")
    print(f"run wall time    : {t_run:.3f} s (exp.process = Mitsuba render)")
    print(f"run CPU time     : {c_run:.3f} s (CPU/wall = "
          f"{c_run / max(t_run, 1e-12):.2f})")
    print(f"postprocess time : {t_post:.3f} s")
    n_samples = args.spp * len(VZA_OURS)
    print(f"throughput       : {n_samples / t_run:.4g} samples/s "
          f"({n_samples} samples)")

    ref = load_ref(args.ref)
    print()
    hdr = f"{'vza':>5} {'BRF':>10} {'stderr(m2)':>11}"
    if ref:
        hdr += f" {'ours':>10} {'ours_se':>9} {'z':>7}"
    print(hdr + "   (vza: ours, - = Sun's side)")
    zs = []
    for i, z in enumerate(signed):
        zi = int(round(z))
        line = f"{zi:+5d} {brf[i]:10.6f} {se[i]:11.3e}"
        if zi in ref:
            rb, rs = ref[zi]
            zz = (brf[i] - rb) / np.hypot(se[i], rs)
            zs.append(zz)
            line += f" {rb:10.6f} {rs:9.2e} {zz:7.2f}"
        print(line)

    print()
    i_max = int(np.argmax(brf))
    print(f"max BRF {brf[i_max]:.6f} at vza {int(round(signed[i_max])):+d} "
          f"(hot spot expected at -20)")
    if moment:
        rel = se / brf
        print(f"relative stderr (2nd moment): median {np.median(rel):.3e}, "
              f"max {np.max(rel):.3e}")
    if zs:
        zs = np.array(zs)
        print(f"z vs ours ({args.ref.name}): n={len(zs)} mean "
              f"{zs.mean():+.2f} rms {np.sqrt(np.mean(zs ** 2)):.2f} "
              f"max|z| {np.max(np.abs(zs)):.2f}")

    if args.csv:
        args.csv.parent.mkdir(parents=True, exist_ok=True)
        with open(args.csv, "w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["vza_ours", "brf", "brf_stderr"])
            for z, b, s in zip(signed, brf, se):
                w.writerow([int(round(z)), f"{b:.10e}", f"{s:.10e}"])
        print(f"wrote {args.csv}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
