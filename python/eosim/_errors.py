"""The exceptions defined by the extension (``python/src/errors.rs``), with the documentation
Python users read (``help(eosim.ConfigError)``, the API page): the extension gives them a
one-line docstring, replaced here by a full one."""

from ._native import ConfigError, SimulationError

ConfigError.__doc__ = """Invalid input: an experiment, a site, a region or an acquisition.

A ``ValueError``. The message is the command-line tools' (``simulate check`` names the same
key for the same input): the file, or ``<dict>`` and ``<string>`` for input given as a dict or
as TOML text, then the key path (``atmosphere.single_scattering_albedo``,
``measures[0].spp``) and what is wrong. For a PICS sweep it also names the acquisition
(``acquisition 1 (2026-01-15T09:45:00Z)``), and for acquisitions given in Python their index
(``acquisitions[0].time_utc``). A missing input file given by path raises
:class:`InputFileNotFoundError`, a subclass.

See Also
--------
InputFileNotFoundError : An input file that does not exist.
SimulationError : A failure while running or writing.
keys : The documented keys of each section of an experiment.

Examples
--------
>>> import eosim
>>> try:
...     eosim.load({
...         "spectral": {"wavelengths": [550.0]},
...         "surface": {"type": "lambertian", "reflectanse": 0.3},
...         "illumination": {"type": "directional", "zenith": 30.0},
...         "measures": [{"id": "toa", "type": "mdistant", "zeniths": [0.0], "azimuth": 0.0}],
...     }, spp=1000)
... except eosim.ConfigError as e:
...     print(e)  # doctest: +ELLIPSIS
<dict>: ...unknown field `reflectanse`...
>>> issubclass(eosim.ConfigError, ValueError)
True
"""

SimulationError.__doc__ = """A failure while running or writing, not caused by invalid input.

A ``RuntimeError``: an output folder that cannot be written, a scene bundle that is missing
its manifest or is damaged, a failed bundle build.
The message carries the chain of causes. A Rust panic inside a run also becomes a
``SimulationError``. :class:`OutputExistsError` (building a bundle into an existing folder) is
a subclass.

See Also
--------
ConfigError : Invalid input.
OutputExistsError : An existing output folder.

Examples
--------
>>> import tempfile
>>> import eosim
>>> empty = tempfile.TemporaryDirectory()
>>> try:
...     eosim.open_bundle(empty.name)
... except eosim.SimulationError as e:
...     print("manifest.toml" in str(e))
True
>>> empty.cleanup()
>>> issubclass(eosim.SimulationError, RuntimeError)
True
"""

__all__ = ["ConfigError", "SimulationError"]
