"""Shared fixtures: the repository, the `simulate` binary (for comparisons with the command
line), the public data folder ``../shared/data`` (tests that need it skip without it)."""

import os
import signal
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
SHARED = REPO.parent / "shared" / "data"

# A small 1D experiment (a Rayleigh layer over a Lambertian ground, principal plane).
RAYLEIGH = {
    "mode": "mono",
    "seed": 3,
    "spectral": {"wavelengths": [450.0, 550.0]},
    "geometry": {"type": "plane_parallel", "toa_altitude": 100.0},
    "atmosphere": {
        "type": "homogeneous",
        "optical_thickness": 0.3,
        "single_scattering_albedo": 1.0,
        "phase": {"type": "rayleigh"},
    },
    "surface": {"type": "lambertian", "reflectance": 0.2},
    "illumination": {"type": "directional", "zenith": 30.0, "azimuth": 0.0},
    "measures": [
        {"id": "toa_pp", "type": "mdistant", "construct": "hplane", "zeniths": [-60.0, 0.0, 60.0],
         "azimuth": 0.0, "spp": 4000},
        {"id": "flux", "type": "distant_flux", "spp": 2000},
    ],
}


@pytest.fixture(scope="session")
def simulate():
    """The release `simulate` binary (built by the README's set-up step)."""
    exe = Path(os.environ.get("EOSIM_SIMULATE", REPO / "target" / "release" / "simulate"))
    if not exe.exists():
        pytest.skip(f"{exe} not built (run scripts/setup.sh)")
    return exe


def run_cli(simulate, experiment, out, *extra):
    subprocess.run([str(simulate), "-q", "run", str(experiment), "-o", str(out), *extra],
                   check=True, capture_output=True)
    return Path(out) / "results.nc"


@pytest.fixture(scope="session")
def shared():
    if not SHARED.is_dir():
        pytest.skip(f"public data folder {SHARED} absent")
    return SHARED


@pytest.fixture(scope="session")
def grenoble_bundle(tmp_path_factory, shared):
    """A 5 km bundle of the Grenoble example region (real DEM and land cover, its trees and
    houses), built through the package."""
    import eosim

    region = eosim.read_toml(REPO / "examples" / "grenoble" / "region.toml")
    region["area"]["bbox"] = [5.70, 45.15, 5.76, 45.20]
    out = tmp_path_factory.mktemp("bundle") / "grenoble_small"
    return eosim.build_bundle(region, out, base_dir=REPO / "examples" / "grenoble")


def ortho_experiment(bundle_path):
    return {
        "seed": 7,
        "spectral": {"wavelengths": [550.0, 660.0]},
        "atmosphere": {"type": "molecular", "profile": "afgl_1986-us_standard",
                       "layer_thickness": 1.0},
        "illumination": {"type": "directional", "zenith": 30.0, "azimuth": 120.0},
        "scene": {"type": "bundle", "path": str(bundle_path)},
        "measures": [{"id": "toa", "type": "ortho", "pixel_size_m": 250.0, "spp": 4}],
    }


@pytest.fixture
def sigint():
    """Python's own SIGINT handler (KeyboardInterrupt) for the duration of a test.

    A process started with SIGINT ignored (a background job of a non-interactive shell, some CI
    runners) keeps it ignored, and `_thread.interrupt_main()` then does nothing: the Ctrl-C
    tests would wait for their whole (deliberately endless) run. They install the handler
    themselves, and the previous one is restored afterwards.
    """
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)
