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
    """``ds.eosim``: one measure at a time from the Dataset of a run.

    Importing ``eosim`` registers this accessor on every ``xarray.Dataset``; it serves the
    results of :func:`eosim.run` and :meth:`Experiment.run` (and a ``results.nc`` reopened
    with xarray, whose ``measure_id`` and ``direction_measure`` it reads). In a run's
    Dataset the non-image measures share the dimensions ``measure`` and ``direction``;
    :meth:`measure` cuts out one of them.

    Parameters
    ----------
    ds : xarray.Dataset
        The Dataset (xarray passes it: write ``ds.eosim``).

    See Also
    --------
    eosim.run : Makes such Datasets.

    Examples
    --------
    >>> import eosim
    >>> ds = eosim.run({
    ...     "spectral": {"wavelengths": [450.0, 550.0]},
    ...     "atmosphere": {"type": "homogeneous", "optical_thickness": 0.1},
    ...     "surface": {"type": "lambertian", "reflectance": 0.3},
    ...     "illumination": {"type": "directional", "zenith": 30.0, "azimuth": 0.0},
    ...     "measures": [
    ...         {"id": "pp", "type": "mdistant", "construct": "hplane", "azimuth": 0.0,
    ...          "zeniths": [-60.0, -30.0, 0.0, 30.0, 60.0]},
    ...         {"id": "up", "type": "distant_flux"},
    ...     ],
    ... }, spp=1000, threads=1, progress=False)
    >>> ds.eosim.measure("pp").brf.dims
    ('wavelength', 'zenith')
    >>> list(ds.eosim.measures())
    ['pp', 'up']
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
        """Every non-image measure of the run, each as :meth:`measure` gives it.

        Returns
        -------
        dict of str to xarray.Dataset
            ``{measure id: Dataset}``, in the experiment's order.

        See Also
        --------
        measure : One measure.

        Examples
        --------
        >>> import eosim
        >>> ds = eosim.run({
        ...     "spectral": {"wavelengths": [450.0, 550.0]},
        ...     "atmosphere": {"type": "homogeneous", "optical_thickness": 0.1},
        ...     "surface": {"type": "lambertian", "reflectance": 0.3},
        ...     "illumination": {"type": "directional", "zenith": 30.0, "azimuth": 0.0},
        ...     "measures": [
        ...         {"id": "pp", "type": "mdistant", "construct": "hplane", "azimuth": 0.0,
        ...          "zeniths": [-60.0, -30.0, 0.0, 30.0, 60.0]},
        ...         {"id": "up", "type": "distant_flux"},
        ...     ],
        ... }, spp=1000, threads=1, progress=False)
        >>> parts = ds.eosim.measures()
        >>> list(parts)
        ['pp', 'up']
        >>> parts["pp"].sizes["zenith"], parts["up"].sizes["direction"]
        (5, 1)
        """
        ids = [str(x) for x in self._ds.measure_id.values]
        return {i: self.measure(i) for i in ids}

    def measure(self, measure_id: str) -> xr.Dataset:
        """The part of the run's Dataset that belongs to one measure.

        Parameters
        ----------
        measure_id : str
            The measure's ``id``, as in the experiment (``ds.measure_id`` lists them).

        Returns
        -------
        xarray.Dataset
            The measure's directions only, its per-measure variables (``measure_type``,
            ``flux_altitude``...) as scalars, and the run's attributes. An ``hplane``
            (principal-plane) measure is indexed by ``zenith``, the view zenith in degrees
            signed as its ``zeniths`` key gives it (negative on the side opposite its
            ``azimuth``), so ``.brf.plot(x="zenith")`` draws the plane unfolded; other
            measures keep the dimension ``direction`` with ``vza`` and ``vaa`` (degrees).
            Variables of other measures' images are kept as they are.

        Raises
        ------
        KeyError
            If the run has no such measure (the message lists its measures). Image
            measures (``ortho``, ``perspective``) are not served here: their variables
            (``ID_brf``...) have dimensions of their own in the Dataset itself.

        See Also
        --------
        measures : Every measure at once.

        Examples
        --------
        >>> import eosim
        >>> ds = eosim.run({
        ...     "spectral": {"wavelengths": [450.0, 550.0]},
        ...     "atmosphere": {"type": "homogeneous", "optical_thickness": 0.1},
        ...     "surface": {"type": "lambertian", "reflectance": 0.3},
        ...     "illumination": {"type": "directional", "zenith": 30.0, "azimuth": 0.0},
        ...     "measures": [
        ...         {"id": "pp", "type": "mdistant", "construct": "hplane", "azimuth": 0.0,
        ...          "zeniths": [-60.0, -30.0, 0.0, 30.0, 60.0]},
        ...         {"id": "up", "type": "distant_flux"},
        ...     ],
        ... }, spp=1000, threads=1, progress=False)
        >>> pp = ds.eosim.measure("pp")
        >>> pp.zenith.values.tolist()
        [-60.0, -30.0, 0.0, 30.0, 60.0]
        >>> pp.vaa.values.tolist()                     # the far side of the plane
        [180.0, 180.0, 0.0, 0.0, 0.0]
        >>> pp.brf.sel(wavelength=550.0, zenith=-30.0).shape
        ()
        >>> str(ds.eosim.measure("up").measure_type.values)
        'distant_flux'
        >>> try:
        ...     ds.eosim.measure("toa")
        ... except KeyError as e:
        ...     print(e)
        "no measure 'toa'; the run's measures are ['pp', 'up']"
        """
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
