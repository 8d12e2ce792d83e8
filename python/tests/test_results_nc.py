"""The Dataset of a run equals the ``results.nc`` the command line writes for the same
experiment and seed (read with ``xarray.open_dataset(..., decode_coords="all")``)."""

import numpy as np
import xarray as xr

import eosim
from conftest import REPO, RAYLEIGH, ortho_experiment, run_cli


def _identical(ds, path):
    ref = xr.open_dataset(path, decode_coords="all")
    # The Dataset is results.nc plus one coordinate, the signed `zenith` (docs/python.md).
    assert "zenith" not in ref.variables
    if "direction" in ds.dims:
        np.testing.assert_array_equal(np.abs(ds.zenith.values), ds.vza.values)
        ds = ds.drop_vars("zenith")
    xr.testing.assert_identical(ds, ref)
    for v in ref.variables:
        assert ds[v].dtype == ref[v].dtype, v
        assert ds[v].attrs == ref[v].attrs or all(
            (ds[v].attrs[k] == ref[v].attrs[k]).all() if hasattr(ref[v].attrs[k], "all")
            else ds[v].attrs[k] == ref[v].attrs[k] for k in ref[v].attrs), v
    assert list(ds.attrs) == list(ref.attrs)


def test_1d_run_equals_results_nc(simulate, tmp_path):
    f = tmp_path / "exp.toml"
    f.write_text(eosim._native.dict_to_toml(RAYLEIGH))
    nc = run_cli(simulate, f, tmp_path / "cli")
    _identical(eosim.run(f, progress=False), nc)


def test_example_with_spp_override_equals_results_nc(simulate, tmp_path):
    f = REPO / "examples" / "rayleigh_lambertian.toml"
    nc = run_cli(simulate, f, tmp_path / "cli", "--spp", "500")
    _identical(eosim.run(f, spp=500, progress=False), nc)


def test_ortho_image_equals_results_nc_and_reads_with_rioxarray(simulate, grenoble_bundle, tmp_path):
    f = tmp_path / "ortho.toml"
    f.write_text(eosim._native.dict_to_toml(ortho_experiment(grenoble_bundle.path)))
    nc = run_cli(simulate, f, tmp_path / "cli")
    ds = eosim.run(f, progress=False)
    _identical(ds, nc)
    import rioxarray  # noqa: F401

    brf = ds.toa_brf
    assert brf.rio.crs is not None
    assert brf.rio.crs.to_wkt() == xr.open_dataset(nc, decode_coords="all").toa_brf.rio.crs.to_wkt()
    assert brf.rio.resolution() == (250.0, -250.0)
    assert np.isnan(brf.rio.nodata)  # issue 42: images carry their no-data value
    assert "toa_spatial_ref" in ds.coords
    assert ds.toa_x.attrs["units"] == "m" and ds.toa_y.attrs["units"] == "m"
