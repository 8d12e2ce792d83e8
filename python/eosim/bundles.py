"""Scene bundles: build one from a region (file, TOML string or dict), open one to inspect it.

A scene bundle is the folder ``scenegen build`` writes: the terrain as triangle tiles, the
materials (BRDFs by land-cover class), the templates of trees and houses and their instances,
and a ``manifest.toml`` describing them. Experiments render it with
``scene = {"type": "bundle", "path": ...}``.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

from . import _native
from ._checks import existing, flag
from ._sources import Source, toml_source


@dataclass(frozen=True)
class Bundle:
    """A scene bundle on disk, as its manifest describes it.

    Returned by :func:`build_bundle` and :func:`open_bundle` (not made directly).
    ``str(bundle)`` (or ``print(bundle)``) gives the summary ``scenegen info`` prints: CRS,
    extent, terrain, materials with their share of the pixels, templates and instances,
    memory.

    Attributes
    ----------
    path : pathlib.Path
        The bundle's folder.
    manifest : dict
        The whole ``manifest.toml`` as a dict.
    summary : str
        The ``scenegen info`` summary (also ``str(bundle)``).
    disk_bytes : int
        Bytes of the bundle's files on disk.
    instanced_triangles : int
        Triangles stored: terrain plus one copy of each template.
    flattened_triangles : float
        Triangles of the scene if every instance were a copy of its template.
    crs : str
        The working CRS (see the property).
    extent : dict
        The working extent (see the property).
    materials : list of dict
        The materials (see the property).
    memory : dict
        Sizes on disk and in triangles (see the property).

    See Also
    --------
    build_bundle : Build a bundle from a region and open it.
    open_bundle : Open an existing bundle.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> import eosim
    >>> region = {                      # a flat 1 km square of bare soil, no input file
    ...     "area": {"centre": [5.72, 45.17], "size_km": 1.0},
    ...     "dem": {"flat_m": 200.0, "spacing_m": 50.0},
    ...     "landcover": {"class": 60, "scheme": "esa_worldcover"},
    ... }
    >>> tmp = tempfile.TemporaryDirectory()
    >>> bundle = eosim.build_bundle(region, pathlib.Path(tmp.name) / "flat")
    >>> bundle.path.name
    'flat'
    >>> bundle.crs.startswith("+proj=tmerc")
    True
    >>> bundle.extent["min"][:2], bundle.extent["max"][:2]
    ([-500.0, -500.0], [500.0, 500.0])
    >>> [m["name"] for m in bundle.materials][:3]
    ['forest_floor', 'shrub', 'grass']
    >>> sorted(bundle.memory)
    ['disk_bytes', 'flattened_triangles', 'instanced_triangles']
    >>> bundle.manifest["crs"]["proj"] == bundle.crs
    True
    >>> print(bundle)  # doctest: +ELLIPSIS
    bundle ... (format eo-scene-bundle v1)
    ...
    >>> tmp.cleanup()
    """

    path: Path
    manifest: dict = field(repr=False)
    summary: str = field(repr=False)
    disk_bytes: int = 0
    instanced_triangles: int = 0
    flattened_triangles: float = 0.0

    @property
    def crs(self) -> str:
        """str: The working CRS of the bundle's coordinates: ``"EPSG:code"`` when it has
        one (``"EPSG:32631"``), else its PROJ string (the default local transverse
        Mercator, ``"+proj=tmerc ..."``) or its WKT."""
        c = self.manifest["crs"]
        if c.get("epsg") is not None:
            return f"EPSG:{c['epsg']}"
        return c.get("proj") or c["wkt"]

    @property
    def extent(self) -> dict:
        """dict: The extent: ``min`` and ``max`` corners (m, in the working CRS),
        ``lon_lat_bbox`` (degrees, ``[west, south, east, north]``) and ``height_range``
        (m)."""
        return self.manifest["extent"]

    @property
    def materials(self) -> list:
        """list of dict: The materials as the manifest lists them: ``index``, ``name``,
        ``brdf`` (a dict with its ``type`` and parameters, spectral ones as ``values`` over
        ``wavelengths_nm``), ``class_codes`` (the land-cover codes mapped to it) and,
        where known, the ``source`` of its optical data."""
        return self.manifest["materials"]

    @property
    def memory(self) -> dict:
        """dict: Sizes: ``disk_bytes`` (bytes on disk), ``instanced_triangles`` (stored:
        terrain plus templates) and ``flattened_triangles`` (if every instance were
        copied)."""
        return {
            "disk_bytes": self.disk_bytes,
            "instanced_triangles": self.instanced_triangles,
            "flattened_triangles": self.flattened_triangles,
        }

    def __str__(self) -> str:
        return self.summary


def open_bundle(path) -> Bundle:
    """Open the scene bundle in a folder.

    The manifest is read and checked, and the files it lists are checked present.

    Parameters
    ----------
    path : str or os.PathLike
        The bundle's folder (the one holding ``manifest.toml``).

    Returns
    -------
    Bundle
        The bundle, with its manifest and summary.

    Raises
    ------
    TypeError
        If `path` is not a str or path-like.
    InputFileNotFoundError
        If the folder does not exist (also a ``FileNotFoundError``).
    SimulationError
        If the folder holds no readable ``manifest.toml``, or the bundle is damaged (a
        listed file missing or of the wrong size).

    See Also
    --------
    build_bundle : Build a bundle from a region.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> import eosim
    >>> region = {                      # a flat 1 km square of bare soil, no input file
    ...     "area": {"centre": [5.72, 45.17], "size_km": 1.0},
    ...     "dem": {"flat_m": 200.0, "spacing_m": 50.0},
    ...     "landcover": {"class": 60, "scheme": "esa_worldcover"},
    ... }
    >>> tmp = tempfile.TemporaryDirectory()
    >>> folder = pathlib.Path(tmp.name) / "flat"
    >>> _ = eosim.build_bundle(region, folder)
    >>> bundle = eosim.open_bundle(folder)
    >>> bundle.extent["height_range"]
    [200.0, 200.0]
    >>> try:
    ...     eosim.open_bundle(tmp.name)          # a folder without a manifest
    ... except eosim.SimulationError as e:
    ...     print("manifest.toml" in str(e))
    True
    >>> tmp.cleanup()
    """
    d = _native.open_bundle(existing(path, "bundle folder"))
    return Bundle(Path(path), **d)


def build_bundle(region: Source, output, *, force: bool = False, base_dir=None) -> Bundle:
    """Build the scene bundle of a region and open it.

    Runs ``scenegen build`` in this process: the terrain from the DEM, the materials from the
    land cover, trees and houses placed by the population rules, written into `output`.
    A build cannot be interrupted midway (Ctrl-C is raised when it returns).

    Parameters
    ----------
    region : str, os.PathLike or dict
        The region: a dict with the keys of a region file, TOML text (a string holding
        ``=`` or a newline) or the path of a region file. Its main tables: ``area``
        (``bbox = [west, south, east, north]`` in degrees, or ``centre = [lon, lat]`` in
        degrees with ``size_km``), ``dem`` (``files``, or ``flat_m``: a flat terrain at
        this height in m, with ``spacing_m``), ``landcover`` (a class raster ``file`` or one
        ``class`` everywhere, and a ``scheme`` such as ``"esa_worldcover"``), and optional
        ``crs``, ``seed``, ``terrain``, ``buildings``, ``trees``, ``templates``,
        ``population``.
    output : str or os.PathLike
        The folder to write the bundle into.
    force : bool, default False
        Replace an existing bundle (or an empty folder) at `output`. Without it an existing
        `output` is refused; with it, a folder that is not a bundle is still refused.
    base_dir : str or os.PathLike, optional
        The folder relative paths inside a dict or string region are taken from (default:
        the folder remembered by a dict from :func:`read_toml`, else the current folder).

    Returns
    -------
    Bundle
        The new bundle, opened.

    Raises
    ------
    TypeError
        If `force` is not a bool, `output` is not a path, or `region` is not a path, a
        string or a dict.
    InputFileNotFoundError
        If `region` is the path of a file that does not exist.
    OutputExistsError
        If `output` exists and `force` is False (also a ``FileExistsError`` and a
        ``SimulationError``).
    ConfigError
        If the region is invalid: the message names the key path.
    SimulationError
        If the build fails (an input raster that cannot be read, `output` not writable or,
        with `force`, an existing folder that is not a bundle).

    See Also
    --------
    open_bundle : Open an existing bundle.
    Bundle : What the returned object holds.

    Examples
    --------
    >>> import pathlib, tempfile
    >>> import eosim
    >>> region = {                      # a flat 1 km square of bare soil, no input file
    ...     "area": {"centre": [5.72, 45.17], "size_km": 1.0},
    ...     "dem": {"flat_m": 200.0, "spacing_m": 50.0},
    ...     "landcover": {"class": 60, "scheme": "esa_worldcover"},
    ... }
    >>> tmp = tempfile.TemporaryDirectory()
    >>> folder = pathlib.Path(tmp.name) / "flat"
    >>> bundle = eosim.build_bundle(region, folder)
    >>> bundle.materials[5]["name"], bundle.materials[5]["class_codes"]
    ('soil', [60])
    >>> try:
    ...     eosim.build_bundle(region, folder)
    ... except eosim.OutputExistsError as e:
    ...     print(e.strerror)
    output folder already exists (pass force=True to replace a bundle)
    >>> bundle = eosim.build_bundle(region, folder, force=True)

    The bundle renders as a 3D scene:

    >>> ds = eosim.run({
    ...     "spectral": {"wavelengths": [550.0]},
    ...     "illumination": {"type": "directional", "zenith": 30.0, "azimuth": 180.0},
    ...     "scene": {"type": "bundle", "path": str(folder)},
    ...     "measures": [{"id": "img", "type": "ortho", "pixel_size_m": 250.0, "spp": 4}],
    ... }, threads=1, progress=False)
    >>> ds.img_brf.dims, ds.img_brf.shape
    (('wavelength', 'img_y', 'img_x'), (1, 4, 4))
    >>> round(float(ds.img_brf.mean()), 2)   # no atmosphere: the soil's reflectance at 550 nm
    0.14
    >>> tmp.cleanup()
    """
    flag("force", force)
    if not isinstance(output, (str, os.PathLike)):
        raise TypeError(f"output must be a folder path, not {type(output).__name__}")
    text, p = toml_source(region, base_dir)
    if os.path.exists(os.fspath(output)) and not force:
        import errno

        raise OutputExistsError(
            errno.EEXIST,
            "output folder already exists (pass force=True to replace a bundle)",
            os.fspath(output),
        )
    _native.build_bundle(text, p, os.fspath(output), force)
    return open_bundle(output)


class OutputExistsError(FileExistsError, _native.SimulationError):
    """Raised by :func:`build_bundle` for an existing output folder without ``force=True``.

    Both a ``FileExistsError`` (its ``filename`` is the folder, ``errno`` is ``EEXIST``) and
    an :class:`eosim.SimulationError`, so either ``except`` clause catches it.

    See Also
    --------
    build_bundle : Its ``force=True`` replaces an existing bundle.

    Examples
    --------
    >>> import tempfile
    >>> import eosim
    >>> taken = tempfile.TemporaryDirectory()
    >>> try:
    ...     eosim.build_bundle({"area": {"centre": [5.72, 45.17], "size_km": 1.0}}, taken.name)
    ... except eosim.OutputExistsError as e:
    ...     print(e.filename == taken.name, isinstance(e, FileExistsError),
    ...           isinstance(e, eosim.SimulationError))
    True True True
    >>> taken.cleanup()
    """
