"""Experiments: load (file, TOML string or dict), inspect, run into an ``xarray.Dataset``.

:func:`load` validates an experiment once (every key checked, every input file read, the scene
built) into an :class:`Experiment`, which runs as often as needed; :func:`run` does both in one
call. The keys of an experiment are listed by :func:`eosim.keys`.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Callable, Optional, Union

import xarray as xr

from . import _native
from ._checks import count, existing
from ._dataset import to_dataset
from ._progress import reporter
from ._sources import Source, toml_source

Progress = Union[bool, Callable[[int, int], None], None]


class Experiment:
    """A validated experiment, ready to run.

    Every key has been checked, every input file read and the scene built when the object is
    made, so :meth:`run` can be called as often as needed without reading anything again.
    Make one with :func:`eosim.load` (a path, a TOML string or a dict) or, explicitly, with
    :meth:`from_file`, :meth:`from_toml` or :meth:`from_dict`; the constructor itself is
    internal.

    Attributes
    ----------
    wavelengths : list of float
        The run's wavelengths, nm.
    measures : list of str
        The measures' ``id`` values, in the experiment's order.
    seed : int
        The seed of every random stream.
    text : str
        The experiment as TOML text, as recorded in the results' ``experiment`` attribute.
    path : pathlib.Path
        The file the experiment came from (``<dict>`` or ``<string>`` otherwise).

    See Also
    --------
    load : Make an Experiment from a path, a TOML string or a dict.
    run : Load and run in one call.

    Examples
    --------
    >>> import eosim
    >>> exp = eosim.load({
    ...     "spectral": {"wavelengths": [550.0]},
    ...     "atmosphere": {"type": "homogeneous", "optical_thickness": 0.1},
    ...     "surface": {"type": "lambertian", "reflectance": 0.3},
    ...     "illumination": {"type": "directional", "zenith": 30.0, "azimuth": 0.0},
    ...     "measures": [{"id": "toa", "type": "mdistant", "construct": "hplane",
    ...                   "azimuth": 0.0, "zeniths": [-30.0, 0.0, 30.0]}],
    ... }, spp=1000)
    >>> exp
    Experiment('<dict>': 1 wavelength(s), measures ['toa'], seed 0)
    >>> exp.wavelengths, exp.measures, exp.seed, str(exp.path)
    ([550.0], ['toa'], 0, '<dict>')
    >>> print(exp.text)  # doctest: +ELLIPSIS
    [atmosphere]
    optical_thickness = 0.1
    ...
    # overridden on the command line: --spp 1000
    <BLANKLINE>
    >>> ds = exp.run(threads=1, progress=False)
    >>> ds.brf.sizes["direction"]
    3
    """

    def __init__(self, native: _native.Experiment):
        self._native = native

    @classmethod
    def from_file(cls, path: Union[str, os.PathLike], *, spp: Optional[int] = None) -> "Experiment":
        """Load and validate an experiment file.

        Relative paths inside the file (phase tables, profiles, bundles) are taken from the
        file's folder, as ``simulate run`` takes them.

        Parameters
        ----------
        path : str or os.PathLike
            The experiment file (TOML). Unlike :func:`load`, a string is always a path.
        spp : int, optional
            Samples per direction (per pixel for images) for every measure, replacing the
            measures' own ``spp`` (as ``simulate run --spp N``); at least 1. None keeps the
            file's values.

        Returns
        -------
        Experiment
            The validated experiment.

        Raises
        ------
        TypeError
            If `path` is not a str or path-like, or `spp` is not an integer.
        ValueError
            If `spp` is less than 1.
        InputFileNotFoundError
            If the file does not exist (also a ``FileNotFoundError`` and a ``ConfigError``).
        ConfigError
            If the experiment is invalid: the message names the file and the key path.

        See Also
        --------
        load : The same from a path, a TOML string or a dict.

        Examples
        --------
        >>> import pathlib, tempfile
        >>> import eosim
        >>> folder = tempfile.TemporaryDirectory()
        >>> f = pathlib.Path(folder.name) / "exp.toml"
        >>> _ = f.write_text('''
        ... [spectral]
        ... wavelengths = [550.0]
        ... [surface]
        ... type = "lambertian"
        ... reflectance = 0.3
        ... [illumination]
        ... type = "directional"
        ... zenith = 30.0
        ... [[measures]]
        ... id = "toa"
        ... type = "mdistant"
        ... azimuth = 0.0
        ... zeniths = [0.0]
        ... spp = 1000
        ... ''')
        >>> exp = eosim.Experiment.from_file(f)
        >>> exp.path == f
        True
        >>> folder.cleanup()
        """
        # A Path, so that a file name holding "=" is not taken for TOML text.
        text, p = toml_source(Path(existing(path, "experiment file")))
        return cls(_native.load_experiment(text, p, count("spp", spp)))

    @classmethod
    def from_toml(cls, text: str, *, base_dir=None, spp: Optional[int] = None) -> "Experiment":
        """Load and validate an experiment given as TOML text.

        Parameters
        ----------
        text : str
            The experiment, as the text of an experiment file. It is named ``<string>`` in
            error messages.
        base_dir : str or os.PathLike, optional
            The folder relative paths inside the text are taken from (default: the current
            folder).
        spp : int, optional
            Samples per direction (per pixel for images) for every measure, replacing the
            measures' own ``spp``; at least 1. None keeps the text's values.

        Returns
        -------
        Experiment
            The validated experiment.

        Raises
        ------
        TypeError
            If `text` is not a str (bytes are refused), or `spp` is not an integer.
        ValueError
            If `spp` is less than 1.
        ConfigError
            If the TOML is malformed or the experiment invalid: the message names
            ``<string>`` and the key path (or the line, for a TOML syntax error).

        See Also
        --------
        load : The same from a path, a TOML string or a dict.

        Examples
        --------
        >>> import eosim
        >>> exp = eosim.Experiment.from_toml('''
        ... [spectral]
        ... wavelengths = [450.0, 550.0]
        ... [surface]
        ... type = "lambertian"
        ... reflectance = 0.3
        ... [illumination]
        ... type = "directional"
        ... zenith = 30.0
        ... [[measures]]
        ... id = "nadir"
        ... type = "mdistant"
        ... azimuth = 0.0
        ... zeniths = [0.0]
        ... ''', spp=1000)
        >>> exp.wavelengths, str(exp.path)
        ([450.0, 550.0], '<string>')
        """
        if not isinstance(text, str):
            raise TypeError(f"text must be a str of TOML, not {type(text).__name__}")
        p = (Path(base_dir) if base_dir is not None else Path()) / "<string>"
        return cls(_native.load_experiment(text, p, count("spp", spp)))

    @classmethod
    def from_dict(cls, d: dict, *, base_dir=None, spp: Optional[int] = None) -> "Experiment":
        """Load and validate an experiment given as a dict.

        The dict has the keys of an experiment file (tables are dicts, arrays of tables lists
        of dicts; :func:`eosim.keys` lists them). It is written as TOML and parsed by the same
        code as a file, so a dict and the equivalent file give the same experiment. ``None``
        values leave a key out; numpy numbers and arrays, tuples and ``range`` objects are
        accepted; a single measure may be given as a dict instead of a list of one, and
        ``spectral.wavelengths`` as one number.

        Parameters
        ----------
        d : dict
            The experiment. It is named ``<dict>`` in error messages.
        base_dir : str or os.PathLike, optional
            The folder relative paths inside the dict are taken from (default: the folder
            remembered by a dict from :func:`eosim.read_toml`, else the current folder).
        spp : int, optional
            Samples per direction (per pixel for images) for every measure, replacing the
            measures' own ``spp``; at least 1. None keeps the dict's values.

        Returns
        -------
        Experiment
            The validated experiment.

        Raises
        ------
        TypeError
            If `d` is not a dict, a value has no TOML form (the message names its key path),
            a key is not a string, or `spp` is not an integer.
        ValueError
            If `spp` is less than 1.
        ConfigError
            If the experiment is invalid: the message names ``<dict>`` and the key path.

        See Also
        --------
        load : The same from a path, a TOML string or a dict.
        read_toml : Read an experiment file into a dict, to change a few keys.

        Examples
        --------
        >>> import eosim
        >>> exp = eosim.Experiment.from_dict({
        ...     "spectral": {"wavelengths": 550.0},
        ...     "surface": {"type": "lambertian", "reflectance": 0.3},
        ...     "illumination": {"type": "directional", "zenith": 30.0},
        ...     "measures": {"id": "toa", "type": "mdistant", "azimuth": 0.0,
        ...                  "zeniths": range(0, 61, 30)},
        ... }, spp=1000)
        >>> exp.wavelengths, exp.measures
        ([550.0], ['toa'])
        """
        if not isinstance(d, dict):
            raise TypeError(f"d must be a dict, not {type(d).__name__}")
        text, p = toml_source(d, base_dir)
        return cls(_native.load_experiment(text, p, count("spp", spp)))

    @property
    def wavelengths(self) -> list:
        """list of float: The run's wavelengths, nm (those sampling the band with
        ``spectral.srf``)."""
        return self._native.wavelengths

    @property
    def measures(self) -> list:
        """list of str: The measures' ``id`` values, in the experiment's order."""
        return self._native.measures

    @property
    def seed(self) -> int:
        """int: The seed of every random stream (the experiment's ``seed``, default 0); a run
        with the same seed gives the same results on any number of threads."""
        return self._native.seed

    @property
    def text(self) -> str:
        """str: The experiment as TOML text, as written into the results' ``experiment``
        attribute (an ``spp`` given at load time is noted at its end)."""
        return self._native.text

    @property
    def path(self):
        """pathlib.Path: The file the experiment came from; ``<dict>`` or ``<string>`` (in the
        ``base_dir`` folder) for an experiment given as a dict or as TOML text."""
        return self._native.path

    def memory(self) -> dict:
        """The memory a run of this experiment needs, in bytes.

        Returns
        -------
        dict
            ``{"results": ..., "scene": ..., "total": ...}``: the bytes of the result
            accumulators, of the scene (0 without a 3D scene) and their sum, as ``int``.

        Examples
        --------
        >>> import eosim
        >>> exp = eosim.load({
        ...     "spectral": {"wavelengths": [550.0]},
        ...     "surface": {"type": "lambertian", "reflectance": 0.3},
        ...     "illumination": {"type": "directional", "zenith": 30.0},
        ...     "measures": [{"id": "toa", "type": "mdistant", "azimuth": 0.0,
        ...                   "zeniths": [0.0, 30.0], "spp": 1000}],
        ... })
        >>> m = exp.memory()
        >>> m["total"] == m["results"] + m["scene"]
        True
        """
        return self._native.memory()

    def run(
        self,
        *,
        progress: Progress = True,
        threads: Optional[int] = None,
        output: Union[str, os.PathLike, None] = None,
    ) -> xr.Dataset:
        """Run the experiment and return its results.

        The run happens in this process with the GIL released (other Python threads run
        meanwhile). Ctrl-C (or Jupyter's interrupt) stops it within one block of samples and
        raises ``KeyboardInterrupt``; nothing is written then.

        Parameters
        ----------
        progress : bool or callable, default True
            True shows a progress bar (tqdm: a widget in Jupyter, text in a terminal; plain
            lines at every 10 % when stderr is a log file); False or None shows nothing; a
            callable is called as ``progress(walks_done, walks_total)``.
        threads : int, optional
            Worker threads, at least 1 (None: every core, or ``RAYON_NUM_THREADS``). The
            results do not depend on it.
        output : str or os.PathLike, optional
            A folder to also write the command line's products into, as ``simulate run -o``
            does: ``results.nc``, ``results.csv``, and for images GeoTIFFs and PNG
            quicklooks. None (the default) writes no file.

        Returns
        -------
        xarray.Dataset
            What ``results.nc`` holds, decoded as ``xarray.open_dataset(path,
            decode_coords="all")`` decodes it: coordinate ``wavelength`` (nm); the
            non-image measures as one table, dimension ``measure`` (``measure_id``,
            ``measure_type``) and dimension ``direction`` (``vza``, ``vaa`` in degrees,
            ``direction_measure_id``), with ``brf``, ``radiance`` (W m-2 sr-1 nm-1),
            ``albedo``, ``flux``... on ``(wavelength, direction)``, each with its
            ``_stderr`` and ``n_samples``; image measures ``ID`` as ``ID_brf`` etc. on
            ``(wavelength, ID_y, ID_x)`` with their CRS as a grid-mapping coordinate. One
            coordinate is added: ``zenith`` along ``direction``, the view zenith signed as
            an ``hplane`` measure's ``zeniths`` give it (``vza`` elsewhere). The attributes
            hold the seed, the Sun's angles and the experiment's text.

        Raises
        ------
        TypeError
            If `threads` is not an integer.
        ValueError
            If `threads` is less than 1.
        SimulationError
            If the run or the writing of `output` fails (e.g. a folder that cannot be
            created or written).
        KeyboardInterrupt
            On Ctrl-C.

        See Also
        --------
        eosim.run : Load and run in one call.
        EosimAccessor.measure : One measure's part of the result (``ds.eosim.measure(id)``).

        Examples
        --------
        >>> import eosim
        >>> exp = eosim.load({
        ...     "spectral": {"wavelengths": [550.0]},
        ...     "atmosphere": {"type": "homogeneous", "optical_thickness": 0.1},
        ...     "surface": {"type": "lambertian", "reflectance": 0.3},
        ...     "illumination": {"type": "directional", "zenith": 30.0, "azimuth": 0.0},
        ...     "measures": [{"id": "toa", "type": "mdistant", "construct": "hplane",
        ...                   "azimuth": 0.0, "zeniths": [-30.0, 0.0, 30.0]}],
        ... }, spp=1000)
        >>> ds = exp.run(threads=1, progress=False)
        >>> ds.brf.dims, ds.brf.attrs["units"]
        (('wavelength', 'direction'), '1')
        >>> ds.zenith.values.tolist()
        [-30.0, 0.0, 30.0]
        >>> bool(((ds.brf > 0.2) & (ds.brf < 0.5)).all())
        True

        A callable receives the progress:

        >>> seen = []
        >>> _ = exp.run(threads=1, progress=lambda done, total: seen.append((done, total)))
        >>> seen[-1][0] == seen[-1][1]
        True
        """
        out = None if output is None else os.fspath(output)
        threads = count("threads", threads)
        with reporter(progress, "simulate", "walks") as cb:
            raw = self._native.run(cb, threads, out)
        return to_dataset(raw)

    def __repr__(self) -> str:
        return (
            f"Experiment({str(self.path)!r}: {len(self.wavelengths)} wavelength(s), "
            f"measures {self.measures}, seed {self.seed})"
        )


def load(source: Source, *, base_dir=None, spp: Optional[int] = None) -> Experiment:
    """Load and validate an experiment from a file, a TOML string or a dict.

    Every key is checked (unknown keys too: a misspelt key is an error), every input file
    read and the scene built, once; the returned :class:`Experiment` then runs as often as
    needed. Units in an experiment: wavelengths in nm, altitudes in km, angles in degrees
    (:func:`eosim.keys` lists every key with its unit and default).

    Parameters
    ----------
    source : str, os.PathLike or dict
        The experiment: a dict with the keys of an experiment file, a string holding TOML
        text (any string containing ``=`` or a newline), or else the path of an experiment
        file. A dict is named ``<dict>`` and a string ``<string>`` in error messages.
    base_dir : str or os.PathLike, optional
        The folder relative paths inside a dict or a string are taken from (default: the
        folder remembered by a dict from :func:`read_toml`, else the current folder). A
        file's relative paths are always taken from its own folder.
    spp : int, optional
        Samples per direction (per pixel for images) for every measure, replacing the
        measures' own ``spp`` (as ``simulate run --spp N``; it also fills measures that
        give none); at least 1. None keeps the experiment's values.

    Returns
    -------
    Experiment
        The validated experiment.

    Raises
    ------
    TypeError
        If `source` is not a path, a string or a dict; if a dict's value has no TOML form
        (the message names its key path) or a key is not a string; if `spp` is not an
        integer.
    ValueError
        If `spp` is less than 1.
    InputFileNotFoundError
        If `source` is the path of a file that does not exist (also a
        ``FileNotFoundError`` and a ``ConfigError``).
    ConfigError
        If the experiment is invalid: a TOML syntax error, an unknown or missing key, a
        value out of range, a measure without ``spp`` when none is given here, an input
        file it names that cannot be read. The message names the file (or ``<dict>``,
        ``<string>``) and the key path, as ``simulate check`` does.

    See Also
    --------
    run : Load and run in one call.
    keys : The documented keys of each section of an experiment.
    read_toml : Read an experiment file into a dict, to change a few keys.

    Examples
    --------
    >>> import eosim
    >>> experiment = {
    ...     "spectral": {"wavelengths": [550.0]},
    ...     "atmosphere": {"type": "homogeneous", "optical_thickness": 0.1},
    ...     "surface": {"type": "lambertian", "reflectance": 0.3},
    ...     "illumination": {"type": "directional", "zenith": 30.0, "azimuth": 0.0},
    ...     "measures": [{"id": "toa", "type": "mdistant", "construct": "hplane",
    ...                   "azimuth": 0.0, "zeniths": [-30.0, 0.0, 30.0]}],
    ... }
    >>> exp = eosim.load(experiment, spp=1000)
    >>> exp.measures
    ['toa']

    Invalid values are reported with their key path:

    >>> experiment["surface"]["reflectance"] = 1.5
    >>> try:
    ...     eosim.load(experiment, spp=1000)
    ... except eosim.ConfigError as e:
    ...     print(e)
    <dict>: `surface.reflectance`: `reflectance` = 1.5 must lie in [0, 1]
    """
    text, p = toml_source(source, base_dir)
    return Experiment(_native.load_experiment(text, p, count("spp", spp)))


def run(
    source: Union[Source, Experiment],
    *,
    progress: Progress = True,
    threads: Optional[int] = None,
    output=None,
    spp: Optional[int] = None,
    base_dir=None,
) -> xr.Dataset:
    """Load and run an experiment; return its results as an ``xarray.Dataset``.

    The same as ``load(source, base_dir=base_dir, spp=spp).run(progress=progress,
    threads=threads, output=output)``: the run happens in this process (no subprocess, no
    file written unless `output` is given) and returns what ``simulate run`` writes into
    ``results.nc``, value for value for the same experiment and seed.

    Parameters
    ----------
    source : str, os.PathLike, dict or Experiment
        The experiment: a dict with the keys of an experiment file, a string of TOML text
        (it holds ``=`` or a newline), the path of an experiment file, or an
        :class:`Experiment` already loaded (then `spp` and `base_dir` are not used: give
        them to :func:`load`).
    progress : bool or callable, default True
        True shows a progress bar (tqdm in Jupyter or a terminal; plain lines at every
        10 % when stderr is a log file); False or None nothing; a callable is called as
        ``progress(walks_done, walks_total)``.
    threads : int, optional
        Worker threads, at least 1 (None: every core). The results do not depend on it.
    output : str or os.PathLike, optional
        A folder to also write the command line's products into (``results.nc``,
        ``results.csv``, GeoTIFFs and PNG quicklooks of images). None writes no file.
    spp : int, optional
        Samples per direction (per pixel for images) for every measure, replacing the
        measures' own ``spp``; at least 1.
    base_dir : str or os.PathLike, optional
        The folder relative paths inside a dict or a string are taken from (default: the
        current folder, or the folder remembered by a dict from :func:`read_toml`).

    Returns
    -------
    xarray.Dataset
        The results, as :meth:`Experiment.run` describes them: ``brf``, ``radiance``
        (W m-2 sr-1 nm-1) and the other quantities on ``(wavelength, direction)`` with
        their standard errors, ``wavelength`` in nm, the view angles ``vza``, ``vaa`` and
        the signed ``zenith`` in degrees, images as ``ID_brf`` etc.

    Raises
    ------
    TypeError
        If `source` is not a path, a string, a dict or an Experiment, a dict's value has no
        TOML form, or `spp` or `threads` is not an integer.
    ValueError
        If `spp` or `threads` is less than 1.
    InputFileNotFoundError
        If `source` is the path of a file that does not exist.
    ConfigError
        If the experiment is invalid (the message names the key path).
    SimulationError
        If the run or the writing of `output` fails.
    KeyboardInterrupt
        On Ctrl-C: the run stops within one block of samples.

    See Also
    --------
    load : Validate once, then run many times.
    pics : Many acquisitions of a calibration site in one call.
    EosimAccessor.measure : One measure's part of the result (``ds.eosim.measure(id)``).

    Examples
    --------
    >>> import eosim
    >>> ds = eosim.run({
    ...     "seed": 1,
    ...     "spectral": {"wavelengths": [550.0]},
    ...     "atmosphere": {"type": "homogeneous", "optical_thickness": 0.1},
    ...     "surface": {"type": "lambertian", "reflectance": 0.3},
    ...     "illumination": {"type": "directional", "zenith": 30.0, "azimuth": 0.0},
    ...     "measures": [
    ...         {"id": "toa", "type": "mdistant", "construct": "hplane", "azimuth": 0.0,
    ...          "zeniths": [-30.0, 0.0, 30.0]},
    ...         {"id": "up", "type": "distant_flux"},
    ...     ],
    ... }, spp=1000, threads=1, progress=False)
    >>> ds.sizes["wavelength"], ds.sizes["measure"], ds.sizes["direction"]
    (1, 2, 4)
    >>> ds.measure_id.values.tolist()
    ['toa', 'up']
    >>> ds.zenith.values.tolist()[:3]
    [-30.0, 0.0, 30.0]
    >>> toa = ds.eosim.measure("toa")
    >>> toa.brf.dims
    ('wavelength', 'zenith')
    >>> bool(0.0 < float(ds.eosim.measure("up").albedo.squeeze()) < 1.0)
    True
    """
    count("spp", spp)
    count("threads", threads)
    exp = source if isinstance(source, Experiment) else load(source, base_dir=base_dir, spp=spp)
    return exp.run(progress=progress, threads=threads, output=output)
