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
    """Simulate the TOA reflectance of a PICS site for each acquisition.

    ``site``: a site file (``docs/pics.md``), TOML string or dict, or a list of them: the
    result then gains a dimension ``site`` (coordinate: each site's ``name``, else its file
    name or position). ``acquisitions``: an
    acquisitions CSV, a pandas DataFrame or a list of dicts with ``time_utc, vza, vaa, srf``
    (and optionally ``sza, saa``). ``vary``: ``{key path: values}`` of one site key (e.g.
    ``{"atmosphere.particle_layers[0].optical_thickness": [0.1, 0.2]}``): the result gains a
    dimension named by the key path. Acquisition ``k`` uses seed ``k`` as in ``simulate pics``.
    The site's data and scene are loaded in this process and reused across acquisitions.
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
