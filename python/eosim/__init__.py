"""eosim: the Earth-observation Monte Carlo radiative-transfer simulator from Python.

Experiments (from a TOML file, a TOML string or a dict with the same keys) run in this process
with the GIL released and return ``xarray.Dataset`` objects holding exactly what the command
line's ``results.nc`` holds; scene bundles are built and inspected; PICS sweeps run many
acquisitions of a calibration site in one call.

* :func:`run`, :func:`load` and :class:`Experiment`: validate and run experiments;
* :func:`pics`: the band TOA reflectance of a calibration site for many acquisitions;
* :func:`build_bundle`, :func:`open_bundle` and :class:`Bundle`: 3D scene bundles;
* :func:`read_toml`: a TOML file as a dict, to change a few keys;
* :func:`keys`: the documented keys, types, units and defaults of every section of an
  experiment;
* ``ds.eosim.measure(id)`` (:class:`EosimAccessor`): one measure of a run's Dataset;
* :class:`ConfigError`, :class:`SimulationError`, :class:`InputFileNotFoundError`,
  :class:`OutputExistsError`: what goes wrong.

Units of experiments: wavelengths in nm, altitudes in km, angles in degrees (azimuths
clockwise from North), positions in a scene in m. Results are seeded: the same experiment and
seed give the same numbers on any number of threads.

Examples
--------
A Rayleigh layer over a Lambertian ground, seen in the principal plane:

>>> import eosim
>>> ds = eosim.run({
...     "spectral": {"wavelengths": [550.0]},
...     "atmosphere": {"type": "homogeneous", "optical_thickness": 0.1},
...     "surface": {"type": "lambertian", "reflectance": 0.3},
...     "illumination": {"type": "directional", "zenith": 30.0, "azimuth": 0.0},
...     "measures": [{"id": "toa", "type": "mdistant", "construct": "hplane",
...                   "azimuth": 0.0, "zeniths": [-30.0, 0.0, 30.0]}],
... }, spp=1000, threads=1, progress=False)
>>> ds.brf.sel(wavelength=550.0).zenith.values.tolist()
[-30.0, 0.0, 30.0]
>>> [k["key"] for k in eosim.keys("illumination")][:3]
['type', 'zenith', 'azimuth']
"""

from ._native import __version__
from ._errors import ConfigError, SimulationError
from ._checks import InputFileNotFoundError
from .bundles import Bundle, OutputExistsError, build_bundle, open_bundle
from .experiment import Experiment, load, run
from ._dataset import EosimAccessor
from ._keys import keys
from ._sources import read_toml
from .pics import pics

__all__ = [
    "Bundle",
    "ConfigError",
    "EosimAccessor",
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
