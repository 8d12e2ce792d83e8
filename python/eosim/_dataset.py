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
    # Image variables carry their no-data value (NaN: pixels with no sample), so that
    # rioxarray's `ds.toa_brf.rio.nodata` is set and `rio.to_raster` writes it.
    for v in ds.data_vars.values():
        if "grid_mapping" in v.encoding and v.dtype.kind == "f":
            v.encoding.setdefault("_FillValue", np.nan)
    return ds
