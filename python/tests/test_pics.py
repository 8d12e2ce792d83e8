"""PICS sweeps: acquisitions from a CSV, a DataFrame or dicts; one Dataset with a time
coordinate, equal to the command line's pics.nc; parameter sweeps; errors."""

import copy

import numpy as np
import pandas as pd
import pytest
import xarray as xr

import eosim
from conftest import REPO, RAYLEIGH

# A site that needs no data files: a Rayleigh layer over a Lambertian sand at Libya-4.
SITE = {
    "name": "test_site",
    "catalogue": "libya4",
    "spp": 2000,
    "wavelength_step": 10.0,
    "atmosphere": {"type": "homogeneous", "optical_thickness": 0.1,
                   "single_scattering_albedo": 1.0, "phase": {"type": "rayleigh"}},
    "surface": {"type": "lambertian", "reflectance": 0.4},
}
ACQS = [
    {"time_utc": "2026-01-15T09:45:00Z", "vza": 5.2, "vaa": 103.0, "srf": "sentinel_2a-msi-4"},
    {"time_utc": "2026-06-15T09:45:00Z", "vza": 5.2, "vaa": 103.0, "srf": "sentinel_2a-msi-3"},
    {"time_utc": "2026-09-15T09:45:00Z", "vza": 0.0, "vaa": 0.0, "srf": "sentinel_2a-msi-4",
     "sza": 30.0, "saa": 150.0},
]


def _csv(path, acqs):
    lines = ["time_utc,vza,vaa,srf,sza,saa"]
    for a in acqs:
        lines.append(f"{a['time_utc']},{a['vza']},{a['vaa']},{a['srf']},{a.get('sza', '')},{a.get('saa', '')}")
    path.write_text("\n".join(lines) + "\n")
    return path


def test_sweep_has_a_time_coordinate_and_one_entry_per_acquisition():
    ds = eosim.pics(SITE, ACQS, progress=False)
    assert ds.sizes["acquisition"] == 3
    assert np.issubdtype(ds.time.dtype, np.datetime64)
    assert "time" in ds.coords and "time" in ds.reflectance.coords
    assert str(ds.time.values[0]).startswith("2026-01-15T09:45")
    assert list(ds.srf.values) == ["sentinel_2a-msi-4", "sentinel_2a-msi-3", "sentinel_2a-msi-4"]
    assert list(ds.sun_angles_given.values) == [0, 0, 1]
    assert float(ds.sza[2]) == 30.0
    assert np.all((ds.reflectance > 0.2) & (ds.reflectance < 0.8))
    assert ds.reflectance.attrs["units"] == "1"


def test_csv_dataframe_and_dicts_are_equivalent(tmp_path):
    a = eosim.pics(SITE, ACQS, progress=False)
    b = eosim.pics(SITE, _csv(tmp_path / "acq.csv", ACQS), progress=False)
    c = eosim.pics(SITE, pd.DataFrame(ACQS), progress=False)
    xr.testing.assert_identical(a, b)
    xr.testing.assert_identical(a, c)


def test_sweep_equals_the_cli_pics_nc(simulate, tmp_path):
    import subprocess

    site = tmp_path / "site.toml"
    site.write_text(eosim._native.dict_to_toml(SITE))
    csv = _csv(tmp_path / "acq.csv", ACQS)
    subprocess.run([str(simulate), "-q", "pics", str(csv), "--site", str(site), "-o", str(tmp_path / "cli")],
                   check=True, capture_output=True)
    ds = eosim.pics(site, csv, progress=False)
    xr.testing.assert_identical(ds, xr.open_dataset(tmp_path / "cli" / "pics.nc", decode_coords="all"))


def test_threads_do_not_change_a_sweep():
    xr.testing.assert_identical(eosim.pics(SITE, ACQS, progress=False, threads=1),
                                eosim.pics(SITE, ACQS, progress=False, threads=2))


def test_parameter_sweep_adds_a_dimension():
    key = "atmosphere.optical_thickness"
    ds = eosim.pics(SITE, ACQS[:2], vary={key: [0.05, 0.5]}, progress=False)
    assert ds.reflectance.dims == (key, "acquisition")
    assert list(ds[key].values) == [0.05, 0.5]
    assert not np.allclose(ds.reflectance[0], ds.reflectance[1])
    # each slice is the sweep of that site
    one = copy.deepcopy(SITE)
    one["atmosphere"]["optical_thickness"] = 0.5
    xr.testing.assert_equal(ds.isel({key: 1}).drop_vars(key), eosim.pics(one, ACQS[:2], progress=False))
    # surface parameters too
    d = eosim.pics({**SITE, "surface": {"type": "rpv", "rho_0": 0.3, "k": 0.85, "g": -0.08}}, ACQS[:1],
                   vary={"surface.rho_0": [0.2, 0.6]}, progress=False)
    assert float(d.reflectance[1, 0]) > float(d.reflectance[0, 0])


def test_progress_counts_acquisitions():
    calls = []
    eosim.pics(SITE, ACQS, progress=lambda d, t: calls.append((d, t)))
    assert calls[-1] == (3, 3)


def test_errors_name_the_key():
    bad = copy.deepcopy(SITE)
    bad["surface"]["reflectance"] = 2.0
    with pytest.raises(eosim.ConfigError, match=r"<dict>.*acquisition 1.*surface\.reflectance"):
        eosim.pics(bad, ACQS, progress=False)
    with pytest.raises(eosim.ConfigError, match="unknown key `latitud`"):
        eosim.pics({**SITE, "latitud": 3.0}, ACQS, progress=False)
    with pytest.raises(eosim.ConfigError, match=r"acquisitions\[0\]\.time_utc"):
        eosim.pics(SITE, [{**ACQS[0], "time_utc": "yesterday"}], progress=False)
    with pytest.raises(eosim.ConfigError, match="unknown key"):
        eosim.pics(SITE, [{**ACQS[0], "sza_deg": 3.0}], progress=False)
    with pytest.raises(eosim.ConfigError, match="both sza and saa"):
        eosim.pics(SITE, [{**ACQS[0], "sza": 3.0}], progress=False)
    with pytest.raises(eosim.ConfigError, match="no `atmosphere.layers`"):
        eosim.pics(SITE, ACQS, vary={"atmosphere.layers[0].tau": [1.0]}, progress=False)
    with pytest.raises(eosim.ConfigError, match="no_such.csv"):
        eosim.pics(SITE, "no_such.csv", progress=False)


def test_example_site_with_its_data(shared):
    site = REPO / "examples" / "pics" / "libya4_site.toml"
    d = eosim.read_toml(site)
    d["spp"] = 200
    d.pop("target_rel_stderr")
    d["integrator"] = {"ckd_walk": "alis"}
    ds = eosim.pics(d, REPO / "examples" / "pics" / "acquisitions.csv", progress=False,
                    base_dir=site.parent)
    assert ds.sizes["acquisition"] == 6
    assert np.all(np.isfinite(ds.reflectance))


def test_several_sites_add_a_site_dimension():
    other = {**SITE, "name": "brighter", "surface": {"type": "lambertian", "reflectance": 0.6}}
    ds = eosim.pics([SITE, other], ACQS[:2], progress=False)
    assert ds.reflectance.dims == ("site", "acquisition")
    assert list(ds.site.values) == ["test_site", "brighter"]
    assert np.all(ds.reflectance.sel(site="brighter") > ds.reflectance.sel(site="test_site"))
    xr.testing.assert_equal(ds.isel(site=0).drop_vars("site"),
                            eosim.pics(SITE, ACQS[:2], progress=False))


def test_ctrl_c_interrupts_a_sweep(sigint):
    import _thread
    import threading

    long = {**SITE, "spp": 2_000_000_000}
    timer = threading.Timer(0.5, _thread.interrupt_main)
    timer.start()
    with pytest.raises(KeyboardInterrupt):
        eosim.pics(long, ACQS, progress=False)
    timer.cancel()


def test_sweep_short_name_one_progress_and_no_repeats():
    seen = []
    ds = eosim.pics(SITE, ACQS[:2], vary={"tau": ("atmosphere.optical_thickness", [0.05, 0.5])},
                    progress=lambda done, total: seen.append((done, total)))
    assert ds.reflectance.dims == ("tau", "acquisition")
    assert ds.tau.attrs["key_path"] == "atmosphere.optical_thickness"
    # The acquisitions' own columns are not repeated along the swept dimension.
    assert "tau" not in ds.vza.dims and "tau" not in ds.time_utc.dims
    # One progress for the whole sweep: one total, counts that only grow, ending at the total.
    assert len({t for _, t in seen}) == 1
    assert [d for d, _ in seen] == sorted(d for d, _ in seen) and seen[-1][0] == seen[-1][1]


def test_progress_in_a_log_is_plain_lines(capsys):
    eosim.run(RAYLEIGH, spp=200, progress=True)
    err = capsys.readouterr().err
    assert "\r" not in err, repr(err)
    lines = [l for l in err.splitlines() if l.startswith("simulate:")]
    assert lines and " walks (" in lines[-1]
    done, total = lines[-1].split(":")[1].split()[0].split("/")
    assert done == total
