"""eosim: the Earth-observation scene simulator from Python.

Experiments (from a TOML file, a TOML string or a dict with the same keys) run in this process
with the GIL released and return ``xarray.Dataset`` objects holding exactly what ``results.nc``
holds; scene bundles are built and inspected; PICS sweeps run many acquisitions of one site in
one call. See ``docs/python.md``.
"""

from ._native import ConfigError, SimulationError, __version__
from ._checks import InputFileNotFoundError
from .bundles import Bundle, OutputExistsError, build_bundle, open_bundle
from .experiment import Experiment, load, run
from ._keys import keys
from ._sources import read_toml
from .pics import pics

__all__ = [
    "Bundle",
    "ConfigError",
    "InputFileNotFoundError",
    "OutputExistsError",
    "Experiment",
    "SimulationError",
    "__version__",
    "build_bundle",
    "keys",
    "load",
    "open_bundle",
    "pics",
    "read_toml",
    "run",
]
