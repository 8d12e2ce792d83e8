"""PICS sweeps: one calibration site, many acquisitions (and optionally many values of one site
parameter), run in this process in one call; one ``xarray.Dataset`` as ``pics.nc`` holds it,
with ``time`` as the acquisitions' coordinate."""

from __future__ import annotations

import copy
import os
import re
from typing import Any, Iterable, Mapping, Optional

import xarray as xr

from . import _native
from ._dataset import to_dataset
from ._progress import parts_reporter, reporter
from ._checks import count, existing
from ._sources import Source, as_dict, toml_source

_COLUMNS = ("time_utc", "vza", "vaa", "srf", "sza", "saa")


def _num(v):
    if v is None:
        return None
    try:
        import math

        f = float(v)
        return None if math.isnan(f) else f
    except (TypeError, ValueError):
        return v


def _rows(acquisitions) -> list:
    """Acquisitions as ``(time_utc, vza, vaa, srf, sza, saa)`` tuples: a CSV path (checked by
    the simulator), a pandas DataFrame, or a list of dicts with those keys."""
    if isinstance(acquisitions, (str, os.PathLike)):
        return _native.read_acquisitions(existing(acquisitions, "acquisitions file"))
    if hasattr(acquisitions, "to_dict"):  # pandas DataFrame
        acquisitions = acquisitions.to_dict("records")
    if not isinstance(acquisitions, Iterable) or isinstance(acquisitions, (bytes, Mapping)):
        raise TypeError("acquisitions must be a CSV file path, a pandas DataFrame or a list of "
                        f"dicts, not {type(acquisitions).__name__}")
    rows = []
    for k, a in enumerate(acquisitions):
        if not isinstance(a, Mapping):
            raise _native.ConfigError(f"acquisitions[{k}]: expected a dict with keys {_COLUMNS}")
        unknown = set(a) - set(_COLUMNS)
        if unknown:
            raise _native.ConfigError(
                f"acquisitions[{k}]: unknown key(s) {sorted(unknown)} (known: {', '.join(_COLUMNS)})"
            )
        missing = [c for c in _COLUMNS[:4] if c not in a]
        if missing:
            raise _native.ConfigError(f"acquisitions[{k}]: missing key(s) {missing}")
        t = a["time_utc"]
        t = t.isoformat() if hasattr(t, "isoformat") else str(t)
        if "T" in t and not (t.endswith("Z") or re.search(r"[+-]\d\d:\d\d$", t)):
            t += "Z"  # naive times are UTC
        rows.append(
            (t, float(a["vza"]), float(a["vaa"]), str(a["srf"]), _num(a.get("sza")), _num(a.get("saa")))
        )
    return rows


_STEP = re.compile(r"([^.\[\]]+)|\[(\d+)\]")


def _set(d: dict, key: str, value: Any) -> None:
    """Set ``value`` at key path ``key`` (``atmosphere.particle_layers[0].optical_thickness``);
    every table and list on the way must exist (the last key may be new)."""
    steps = [m.group(1) if m.group(1) is not None else int(m.group(2)) for m in _STEP.finditer(key)]

    def shown(n):
        return "".join(f"[{s}]" if isinstance(s, int) else ("." if i else "") + s
                       for i, s in enumerate(steps[:n]))

    node = d
    for i, s in enumerate(steps):
        ok = (isinstance(s, int) and isinstance(node, list) and s < len(node)) or (
            isinstance(s, str) and isinstance(node, dict) and (s in node or i == len(steps) - 1))
        if not ok:
            raise _native.ConfigError(f"vary: `{key}`: the site has no `{shown(i + 1)}`")
        if i == len(steps) - 1:
            node[s] = value
        else:
            node = node[s]


def pics(
    site: Source,
    acquisitions,
    *,
    vary: Optional[Mapping[str, Iterable]] = None,
    progress=True,
    threads: Optional[int] = None,
    base_dir=None,
) -> xr.Dataset:
    """Simulate the band TOA reflectance of a calibration site for each acquisition.

    Runs what ``simulate pics`` runs, in this process and in one call: for every acquisition
    (a time, a view direction and a sensor band) the site's experiment is built with the Sun
    at that time and place and the reflectance in that band computed. The site is parsed
    once, its scene built once, and its data files (correlated-k tables, aerosol datasets)
    read once. Acquisition ``k`` (from 1) uses seed ``k``, so the result equals the
    ``pics.nc`` of ``simulate pics`` for the same site and acquisitions.

    Parameters
    ----------
    site : str, os.PathLike, dict, or list of them
        The site: a dict with the keys of a site file, TOML text (a string holding ``=`` or
        a newline) or the path of a site file. Its keys: ``catalogue`` (a CEOS site such as
        ``"libya4"``: its name and coordinates) or ``latitude``, ``longitude`` (degrees),
        ``elevation`` (m), ``spp`` (samples per acquisition and wavelength, default 200000),
        ``target_rel_stderr``, ``wavelength_step`` (nm, default 5), ``mode``, ``irradiance``,
        ``polarized``, and the ``geometry``, ``atmosphere``, ``surface`` (or ``scene``) and
        ``integrator`` tables of an experiment (:func:`eosim.keys` documents those). A list
        of sites runs the same acquisitions at each: the result gains a dimension ``site``
        whose coordinate holds each site's ``name`` (else its catalogue name, file name or
        position).
    acquisitions : str, os.PathLike, pandas.DataFrame or list of dict
        An acquisitions CSV file (checked as ``simulate pics`` checks it), or rows with the
        columns ``time_utc`` (RFC 3339 text, or a ``datetime``/``Timestamp``; naive times are
        UTC), ``vza`` and ``vaa`` (the view zenith and azimuth, degrees, azimuth clockwise
        from North from the site to the sensor), ``srf`` (the band: an embedded name such as
        ``"sentinel_2a-msi-4"`` or a CSV file), and optionally both ``sza`` and ``saa`` (the
        Sun's angles in degrees, replacing the computed solar position).
    vary : dict, optional
        Sweep one site key over values: ``{"name": (key_path, values)}`` adds a dimension
        ``name`` (its coordinate holds the values, its ``key_path`` attribute the key path);
        ``{key_path: values}`` names the dimension by the key path. A key path joins tables
        with ``.`` and list items with ``[i]``, e.g.
        ``"atmosphere.particle_layers[0].optical_thickness"``; every step but the last must
        exist in the site. Only the swept variables gain the dimension; the acquisitions'
        own columns do not.
    progress : bool or callable, default True
        True shows one progress bar for the whole call (plain lines at every 10 % when
        stderr is a log file); False or None nothing; a callable is called as
        ``progress(acquisitions_done, acquisitions_total)``.
    threads : int, optional
        Worker threads, at least 1 (None: every core). The results do not depend on it.
    base_dir : str or os.PathLike, optional
        The folder relative paths inside a dict or string site are taken from (default: the
        folder remembered by a dict from :func:`read_toml`, else the current folder).

    Returns
    -------
    xarray.Dataset
        Dimension ``acquisition`` (coordinate: the row number, from 1) with ``time`` (the
        acquisition time, ``datetime64``) as its CF time coordinate, and per acquisition:
        ``reflectance`` (band TOA reflectance π L / (E0 cos SZA), unitless) and
        ``radiance`` (W m-2 sr-1 nm-1) with their ``_stderr``, ``band_irradiance``
        (W m-2 nm-1), ``vza``, ``vaa``, ``sza``, ``saa`` (degrees), ``earth_sun_distance``
        (au), ``srf``, ``time_utc`` and ``sun_angles_given``. `vary` adds its dimension in
        front of ``acquisition``, a list of sites the dimension ``site``.

    Raises
    ------
    TypeError
        If `threads` is not an integer, `site` is not a path, a string, a dict or a list
        of them, or `acquisitions` is not a path, a DataFrame or a list.
    ValueError
        If `threads` is less than 1.
    InputFileNotFoundError
        If the site file or the acquisitions file does not exist.
    ConfigError
        If the site is invalid (the message names the acquisition and the key path), an
        acquisition is (``acquisitions[k].time_utc``; an unknown or missing column, ``sza``
        without ``saa``), or `vary` names a key path the site lacks or more than one key.
    SimulationError
        If a run fails.
    KeyboardInterrupt
        On Ctrl-C: the sweep stops within one block of samples.

    See Also
    --------
    run : One experiment.
    read_toml : Read a site file into a dict, to change a few keys.

    Examples
    --------
    >>> import eosim
    >>> site = {
    ...     "catalogue": "libya4",          # the CEOS site's coordinates
    ...     "spp": 1000,
    ...     "atmosphere": {"type": "homogeneous", "optical_thickness": 0.1},
    ...     "surface": {"type": "lambertian", "reflectance": 0.4},
    ... }
    >>> acquisitions = [
    ...     {"time_utc": "2026-01-15T09:45:00Z", "vza": 5.2, "vaa": 103.0,
    ...      "srf": "sentinel_2a-msi-4"},
    ...     {"time_utc": "2026-06-15T09:45:00Z", "vza": 5.2, "vaa": 103.0,
    ...      "srf": "sentinel_2a-msi-4"},
    ... ]
    >>> ds = eosim.pics(site, acquisitions, threads=1, progress=False)
    >>> ds.reflectance.dims, ds.reflectance.attrs["units"]
    (('acquisition',), '1')
    >>> [str(t)[:10] for t in ds.time.values]
    ['2026-01-15', '2026-06-15']
    >>> bool(ds.sza[0] > ds.sza[1])                  # a lower Sun in January
    True

    Sweep the optical thickness, naming the new dimension ``aot``:

    >>> aot = eosim.pics(site, acquisitions, threads=1, progress=False,
    ...                  vary={"aot": ("atmosphere.optical_thickness", [0.05, 0.5])})
    >>> aot.reflectance.dims, aot.aot.attrs["key_path"]
    (('aot', 'acquisition'), 'atmosphere.optical_thickness')
    >>> aot.aot.values.tolist()
    [0.05, 0.5]
    """
    count("threads", threads)
    if isinstance(site, (list, tuple)):
        return _sites(site, acquisitions, vary=vary, progress=progress, threads=threads,
                      base_dir=base_dir)
    rows = _rows(acquisitions)
    if not vary:
        text, path = toml_source(site, base_dir)
        return _sweep(text, path, rows, progress, threads)
    if len(vary) != 1:
        raise _native.ConfigError("vary: give one key path (nest calls to vary more)")
    (name, spec), = vary.items()
    # {name: (key path, values)} names the dimension `name`; {key path: values} by the path.
    if isinstance(spec, tuple) and len(spec) == 2 and isinstance(spec[0], str):
        key, values = spec
    else:
        key, values = name, spec
    values = list(values)
    base, path = as_dict(site, base_dir)
    parts = []
    with parts_reporter(progress, "pics", "acquisitions", len(values)) as part:
        for k, v in enumerate(values):
            d = copy.deepcopy(base)
            _set(d, key, v)
            parts.append(_sweep(_native.dict_to_toml(d), path, rows, part(k), threads))
    # The swept variables gain the dimension; the acquisitions' own columns (time, angles,
    # band, Sun) are the same at every value and stay as they are.
    coord = xr.DataArray(values, dims=name, name=name, attrs={"key_path": key})
    return xr.concat(parts, dim=coord, data_vars="different", coords="minimal",
                     compat="equals", join="exact")


def _sweep(text, path, rows, progress, threads) -> xr.Dataset:
    with reporter(progress, "pics", "acquisitions") as cb:
        raw = _native.pics_sweep(text, path, rows, cb, threads)
    return to_dataset(raw)


def _sites(sites, acquisitions, **kw) -> xr.Dataset:
    """The same acquisitions at several sites, along a dimension ``site``."""
    names, parts = [], []
    for k, s in enumerate(sites):
        d, path = as_dict(s, kw.get("base_dir"))
        names.append(str(d.get("name") or d.get("catalogue") or
                         (path.stem if path.name not in ("<dict>", "<string>") else k)))
        parts.append(pics(s, acquisitions, **kw))
    if len(set(names)) != len(names):
        names = [f"{n}#{k}" for k, n in enumerate(names)]
    ds = xr.concat(parts, dim=xr.DataArray(names, dims="site", name="site"), data_vars="all",
                   coords="minimal", compat="equals", join="exact")
    ds.attrs["site_file"] = [str(p.attrs.get("site_file", "")) for p in parts]
    return ds
