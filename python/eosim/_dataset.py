"""The contents of a netCDF file written in memory by the simulator (``_native``) as an
``xarray.Dataset``, decoded as ``xarray.open_dataset`` decodes the same file on disk
with ``decode_coords="all"`` (``coordinates`` and ``grid_mapping`` attributes, CF time units)."""

from __future__ import annotations

import numpy as np
import xarray as xr


def _attr(v):
    if isinstance(v, tuple) and len(v) == 4 and v[0] == "__num__":
        _, dtype, data, scalar = v
        a = np.frombuffer(data, dtype=np.dtype(dtype).newbyteorder("=")).copy()
        return a[0] if scalar else a
    return v


def _attrs(d):
    return {k: _attr(v) for k, v in d.items()}


def to_dataset(raw: dict) -> xr.Dataset:
    """Build and CF-decode the dataset of a ``_native`` result."""
    variables = {}
    for name, dims, shape, dtype, data, attrs in raw["variables"]:
        if dtype == "str":
            values = np.array(data, dtype=str).reshape(shape)
        else:
            values = np.frombuffer(data, dtype=np.dtype(dtype)).reshape(shape).copy()
        variables[name] = xr.Variable(dims, values, attrs=_attrs(attrs))
    ds = xr.Dataset(variables, attrs=_attrs(raw["attrs"]))
    # decode_coords="all": the grid-mapping variables of ortho images become coordinates, so
    # rioxarray finds the CRS of every image variable (`ds.toa_brf.rio.crs`).
    ds = xr.decode_cf(ds, decode_coords="all")
    ds = _signed_zenith(ds)
    # Image variables carry their no-data value (NaN: pixels with no sample), so that
    # rioxarray's `ds.toa_brf.rio.nodata` is set and `rio.to_raster` writes it.
    for v in ds.data_vars.values():
        if "grid_mapping" in v.encoding and v.dtype.kind == "f":
            v.encoding.setdefault("_FillValue", np.nan)
    return ds


def _hplane_azimuths(ds: xr.Dataset) -> dict:
    """``{measure index: azimuth}`` of the experiment's ``hplane`` measures (from the
    experiment text the dataset carries)."""
    text = ds.attrs.get("experiment")
    if not isinstance(text, str):
        return {}
    from . import _native

    try:
        measures = _native.toml_to_dict(text, "<experiment>").get("measures", [])
    except Exception:  # a result without a readable experiment: no signed zeniths
        return {}
    return {
        k: float(m.get("azimuth", 0.0))
        for k, m in enumerate(measures)
        if isinstance(m, dict) and m.get("construct") == "hplane"
    }


def _signed_zenith(ds: xr.Dataset) -> xr.Dataset:
    """A ``zenith`` coordinate along ``direction``: the signed view zenith of ``hplane``
    (principal-plane) measures, as their ``zeniths`` key gives it (negative on the side
    opposite the plane's ``azimuth``), and ``vza`` elsewhere; so ``ds.brf.plot(x="zenith")``
    draws a principal plane unfolded, as Eradiate does."""
    if "direction" not in ds.dims or "vza" not in ds.coords or "direction_measure" not in ds.coords:
        return ds
    vza = ds.vza.values.astype(float)
    zen = vza.copy()
    planes = _hplane_azimuths(ds)
    if planes and "vaa" in ds.coords:
        vaa = ds.vaa.values.astype(float)
        owner = ds.direction_measure.values
        for i in range(zen.size):
            az = planes.get(int(owner[i]))
            if az is None or not np.isfinite(vaa[i]):
                continue
            # The far side of the plane: the view azimuth is the plane's + 180°.
            d = (vaa[i] - az) % 360.0
            if abs(d - 180.0) < 1e-6 and vza[i] != 0.0:
                zen[i] = -vza[i]
    attrs = {"long_name": "view zenith angle, signed in principal-plane (hplane) measures",
             "units": "degree"}
    return ds.assign_coords(zenith=("direction", zen, attrs))


@xr.register_dataset_accessor("eosim")
class EosimAccessor:
    """``ds.eosim``: views of a run's Dataset.

    ``ds.eosim.measure("toa")`` is the Dataset of one measure: its directions only (indexed by
    the signed ``zenith`` for ``hplane`` measures, so ``.brf.plot(x="zenith")`` needs no
    selection), its per-measure variables as scalars, the run's attributes.
    ``ds.eosim.measures()`` is ``{id: Dataset}`` for every measure.
    """

    def __init__(self, ds: xr.Dataset):
        self._ds = ds
        self._planes = None

    def _hplanes(self) -> dict:
        # Parsed from the experiment text once per Dataset (xarray keeps the accessor).
        if self._planes is None:
            self._planes = _hplane_azimuths(self._ds)
        return self._planes

    def measures(self) -> dict:
        ids = [str(x) for x in self._ds.measure_id.values]
        return {i: self.measure(i) for i in ids}

    def measure(self, measure_id: str) -> xr.Dataset:
        ds = self._ds
        ids = [str(x) for x in ds.measure_id.values]
        if measure_id not in ids:
            raise KeyError(f"no measure {measure_id!r}; the run's measures are {ids}")
        k = ids.index(measure_id)
        out = ds.isel(measure=k)
        if "direction" in ds.dims and "direction_measure" in ds.coords:
            keep = np.flatnonzero(ds.direction_measure.values == k)
            out = out.isel(direction=keep)
            if k in self._hplanes() and "zenith" in out.coords:
                out = out.swap_dims(direction="zenith")
        return out
