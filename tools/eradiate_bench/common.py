"""What the Eradiate peer benchmarks (bench.py, hom.py) share: the offline settings, the
render scheduling options and their kernel dictionary, the kernel start-up banner, and the
reading of a multi-distant result into signed zeniths, BRFs and standard errors.

Import this module before Eradiate: it sets the environment Eradiate reads at import.
"""

from __future__ import annotations

import os

# Must be set before Eradiate is imported (its settings are read at import).
os.environ.setdefault("ERADIATE_OFFLINE", "true")  # never try to download data
os.environ.setdefault("ERADIATE_PROGRESS", "none")  # no progress bars


def add_scheduling_args(p) -> None:
    """The options that schedule Mitsuba's render (shared by both benchmarks)."""
    p.add_argument("--threads", type=int, default=2,
                   help="total render threads. Mitsuba's scalar renderer "
                        "uses the calling thread plus the Dr.Jit pool, so "
                        "this calls drjit.set_thread_count(threads - 1)")
    p.add_argument("--block-size", type=int, default=1,
                   help="Mitsuba integrator block_size (pixels = directions "
                        "per work item). Mitsuba's automatic choice (32) "
                        "puts 32 of the 35 directions in one block, i.e. ~1 "
                        "busy thread; 1 balances the load. 0 = Mitsuba auto")
    p.add_argument("--passes", type=int, default=-1,
                   help="split the spp of each direction into this many "
                        "passes (Mitsuba samples_per_pass = spp/passes) so "
                        "that work items are small and balanced; must "
                        "divide spp. -1 = largest of 64,32,...,1 dividing "
                        "spp; 1 = Mitsuba default (single pass)")
    p.add_argument("--mitsuba-defaults", action="store_true",
                   help="out-of-the-box scheduling: same as --block-size 0 "
                        "--passes 1 (expect poor 2-thread scaling)")
    p.add_argument("--verbose", action="store_true",
                   help="show Mitsuba Info log (prints the render job line "
                        "with the thread and pass counts)")
    p.add_argument("--no-moment", action="store_true",
                   help="do not accumulate the 2nd moment (no in-run variance "
                        "estimate); slightly cheaper per sample")


def resolve_scheduling(args) -> str | None:
    """Fill in `args.block_size` and `args.passes`; an error message if they are invalid."""
    if args.spp < 1 or args.threads < 1:
        return "--spp and --threads must be >= 1"
    if args.mitsuba_defaults:
        args.block_size, args.passes = 0, 1
    if args.passes == -1:
        args.passes = next(p for p in (64, 32, 16, 8, 4, 2, 1)
                           if args.spp % p == 0)
    if args.passes < 1 or args.spp % args.passes:
        return "--passes must be >= 1 and divide --spp"
    return None


def scheduling_kdict(spp: int, block_size: int, passes: int) -> dict:
    """Extra kernel (Mitsuba) dictionary entries for the top-level integrator (with
    moment=True that is Eradiate's 'stokes_moment' wrapper, which owns the render loop)."""
    kdict = {}
    if block_size > 0:
        kdict["integrator.block_size"] = block_size
    if passes > 1:
        kdict["integrator.samples_per_pass"] = spp // passes
    return kdict


def start_kernel(args, dr, mi, eradiate) -> None:
    """Set the render threads and the log level, and print the versions and scheduling."""
    # Mitsuba's scalar render loop (dr.parallel_for on the nanothread pool)
    # also runs work on the calling thread: N pool workers => N+1 threads.
    dr.set_thread_count(args.threads - 1)
    mi.set_log_level(mi.LogLevel.Info if args.verbose else mi.LogLevel.Error)
    try:
        from importlib.metadata import version
        kernel_pkg = f"eradiate-mitsuba {version('eradiate-mitsuba')}"
    except Exception:  # pragma: no cover
        kernel_pkg = "eradiate-mitsuba ?"
    print(f"eradiate {eradiate.__version__} | kernel: {kernel_pkg} "
          f"(mitsuba {mi.__version__}, variant {mi.variant()}) | "
          f"drjit {dr.__version__}")
    print(f"mode: {eradiate.mode().id} | offline: "
          f"{eradiate.config.settings.offline} | render threads: "
          f"{dr.thread_count() + 1} (calling thread + {dr.thread_count()} "
          f"Dr.Jit pool workers) | integrator: {args.integrator} | "
          f"moment: {not args.no_moment}")
    print(f"scheduling: block_size={args.block_size or 'auto'} "
          f"passes={args.passes} (samples_per_pass="
          f"{args.spp // args.passes})")


def brf_result(ds):
    """(vza, vaa, brf, stderr) of a multi-distant result; stderr is None without moments."""
    import numpy as np
    vza = ds["vza"].values.ravel()
    vaa = ds["vaa"].values.ravel()
    brf = ds["brf"].values.ravel()
    se = None
    if "radiance_var" in ds:
        rad = ds["radiance"].values.ravel()
        var = ds["radiance_var"].values.ravel()  # variance of the mean
        # BRF = pi L / (E cos SZA): same scale factor for the stderr
        se = np.sqrt(np.maximum(var, 0.0)) * brf / rad
    return vza, vaa, brf, se


def signed_zeniths(vza, vaa, positive_azimuth: float):
    """Eradiate's (vza, vaa) as signed zeniths: + where vaa is `positive_azimuth`, − at the
    opposite azimuth (an hplane measure's two half-planes)."""
    import numpy as np
    dphi = (vaa - positive_azimuth) % 360.0
    return np.where(np.isclose(dphi, 0.0) | np.isclose(dphi, 360.0), vza, -vza)
