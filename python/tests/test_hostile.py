"""Hostile inputs from Python (issue 42): each raises the exception a Python user expects
(``TypeError``/``ValueError`` naming the argument, ``FileNotFoundError`` for a missing file,
``FileExistsError`` for an existing output, :class:`eosim.ConfigError` naming the key path for a
bad experiment value) and never an ``OverflowError``, a panic or a Rust type name."""

import copy
import os

import numpy as np
import pytest

import eosim
from conftest import RAYLEIGH


def with_(path, value):
    """RAYLEIGH with the value at ``path`` (keys and list indices) replaced."""
    d = copy.deepcopy(RAYLEIGH)
    node = d
    for k in path[:-1]:
        node = node[k]
    node[path[-1]] = value
    return d


def without(path):
    d = copy.deepcopy(RAYLEIGH)
    node = d
    for k in path[:-1]:
        node = node[k]
    del node[path[-1]]
    return d


# (case, call, exception, regex the message must match)
ARGUMENTS = [
    ("negative spp", lambda: eosim.run(RAYLEIGH, spp=-5, progress=False), ValueError, r"spp = -5"),
    ("zero spp", lambda: eosim.load(RAYLEIGH, spp=0), ValueError, r"spp = 0"),
    ("float spp", lambda: eosim.load(RAYLEIGH, spp=10.5), TypeError, r"spp must be an integer"),
    ("string spp", lambda: eosim.load(RAYLEIGH, spp="100"), TypeError, r"spp must be an integer"),
    ("bool spp", lambda: eosim.load(RAYLEIGH, spp=True), TypeError, r"spp"),
    ("negative threads", lambda: eosim.run(RAYLEIGH, threads=-1, progress=False), ValueError, r"threads = -1"),
    ("zero threads", lambda: eosim.load(RAYLEIGH, spp=10).run(threads=0, progress=False), ValueError, r"threads = 0"),
    ("float threads", lambda: eosim.run(RAYLEIGH, threads=2.0, progress=False), TypeError, r"threads"),
    ("missing experiment file", lambda: eosim.run("no_such_experiment.toml"), FileNotFoundError, r"no_such_experiment\.toml"),
    ("missing file via from_file", lambda: eosim.Experiment.from_file("absent.toml"), FileNotFoundError, r"absent\.toml"),
    ("missing file is also a ConfigError", lambda: eosim.load("absent2.toml"), eosim.ConfigError, r"absent2\.toml"),
    ("number as a source", lambda: eosim.load(42), TypeError, r"path, a TOML string or a dict"),
    ("from_dict of a list", lambda: eosim.Experiment.from_dict([1, 2]), TypeError, r"d must be a dict"),
    ("from_toml of bytes", lambda: eosim.Experiment.from_toml(b"seed = 1"), TypeError, r"text must be a str"),
    ("from_file of a number", lambda: eosim.Experiment.from_file(7), TypeError, r"experiment file must be a path, not int"),
    ("bundle folder as a number", lambda: eosim.open_bundle(7), TypeError, r"bundle folder must be a path, not int"),
    ("acquisitions as a number", lambda: eosim.pics(RAYLEIGH, 7, progress=False), TypeError, r"acquisitions must be a CSV file path"),
    ("missing bundle folder", lambda: eosim.open_bundle("no_such_bundle"), FileNotFoundError, r"no_such_bundle"),
    ("missing acquisitions file", lambda: eosim.pics(RAYLEIGH, "no_such.csv", progress=False), FileNotFoundError, r"no_such\.csv"),
    ("negative pics threads", lambda: eosim.pics(RAYLEIGH, [], threads=-2, progress=False), ValueError, r"threads = -2"),
    ("missing region file", lambda: eosim.build_bundle("no_region.toml", "out_x"), FileNotFoundError, r"no_region\.toml"),
    ("force not a bool", lambda: eosim.build_bundle("no_region.toml", "out_x", force="yes"), TypeError, r"force must be True or False"),
]

KEYS = [
    ("albedo out of range", with_(["atmosphere", "single_scattering_albedo"], 1.5), r"atmosphere\.single_scattering_albedo"),
    ("negative optical thickness", with_(["atmosphere", "optical_thickness"], -0.1), r"atmosphere\.optical_thickness"),
    ("NaN optical thickness", with_(["atmosphere", "optical_thickness"], float("nan")), r"atmosphere\.optical_thickness"),
    ("string zenith", with_(["illumination", "zenith"], "30"), r"illumination\.zenith"),
    ("zenith beyond 90", with_(["illumination", "zenith"], 95.0), r"illumination\.zenith"),
    ("misspelt key", with_(["surface", "reflectanse"], 0.2), r"reflectanse"),
    ("reflectance above one", with_(["surface", "reflectance"], 1.2), r"surface\.reflectance"),
    ("unknown surface type", with_(["surface", "type"], "velvet"), r"velvet"),
    ("negative wavelength", with_(["spectral", "wavelengths"], [-450.0]), r"spectral\.wavelengths"),
    ("empty wavelengths", with_(["spectral", "wavelengths"], []), r"spectral\.wavelengths"),
    ("measure spp negative", with_(["measures", 0, "spp"], -5), r"measures\[0\]\.spp"),
    ("measure zenith as string", with_(["measures", 0, "zeniths"], [0.0, "30"]), r"measures\[0\]\.zeniths"),
    ("measure type unknown", with_(["measures", 0, "type"], "camera"), r"camera"),
    ("no illumination", without(["illumination"]), r"illumination"),
    ("no measures", without(["measures"]), r"measures"),
    ("atmosphere type unknown", with_(["atmosphere", "type"], "soup"), r"soup"),
    ("seed negative", with_(["seed"], -1), r"seed"),
    ("phase g out of range", with_(["atmosphere", "phase"], {"type": "hg", "g": 1.5}), r"atmosphere\.phase"),
]


@pytest.mark.parametrize("name,call,exc,pattern", ARGUMENTS, ids=[a[0] for a in ARGUMENTS])
def test_bad_arguments(name, call, exc, pattern, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(exc, match=pattern) as info:
        call()
    assert not isinstance(info.value, OverflowError)
    for word in ("u64", "f64", "usize", "panicked"):
        assert word not in str(info.value), str(info.value)


@pytest.mark.parametrize("name,d,pattern", KEYS, ids=[k[0] for k in KEYS])
def test_bad_values_name_the_key(name, d, pattern):
    with pytest.raises(eosim.ConfigError, match=pattern) as info:
        eosim.load(d)
    msg = str(info.value)
    assert "<dict>" in msg, msg
    for word in ("u64", "f64", "usize", "panicked"):
        assert word not in msg, msg


def test_from_file_takes_a_name_holding_equals_as_a_path(tmp_path, monkeypatch):
    # load() reads a string holding "=" as TOML text; from_file() always reads a file.
    monkeypatch.chdir(tmp_path)
    (tmp_path / "tau=0.3.toml").write_text(eosim._native.dict_to_toml(RAYLEIGH))
    assert eosim.Experiment.from_file("tau=0.3.toml").measures == ["toa_pp", "flux"]


def test_existing_bundle_output_says_force_true(tmp_path):
    (tmp_path / "taken").mkdir()
    region = tmp_path / "region.toml"
    region.write_text("seed = 1\n")
    with pytest.raises(FileExistsError, match=r"force=True") as info:
        eosim.build_bundle(region, tmp_path / "taken")
    assert isinstance(info.value, eosim.SimulationError)
    assert "--force" not in str(info.value)


def test_read_toml_remembers_its_folder(tmp_path, monkeypatch):
    # An experiment whose phase table is a relative path: read as a dict, changed and run
    # from another folder, it still finds the table (the dict remembers the file's folder).
    import shutil

    from conftest import REPO

    (tmp_path / "exp").mkdir()
    shutil.copy(REPO / "simulator/tests/data/fixtures/watercloud.mie.cdf", tmp_path / "exp")
    d = copy.deepcopy(RAYLEIGH)
    d["atmosphere"]["phase"] = {"type": "tabulated", "file": "watercloud.mie.cdf", "wavelength": 800.0}
    d["spectral"]["wavelengths"] = [800.0]
    (tmp_path / "exp" / "e.toml").write_text(eosim._native.dict_to_toml(d))
    monkeypatch.chdir(tmp_path)
    back = eosim.read_toml(os.path.join("exp", "e.toml"))
    assert back.base_dir is not None and back.base_dir.name == "exp"
    back["seed"] = 9
    exp = eosim.load(back, spp=10)
    assert exp.seed == 9


def test_pics_of_a_read_toml_site_finds_its_files(tmp_path, monkeypatch):
    # Used to end in "netcdf error(2)": the dict had lost the folder its relative paths need.
    from conftest import REPO

    site = eosim.read_toml(REPO / "examples/pics/libya4_site.toml")
    monkeypatch.chdir(tmp_path)
    row = {"time_utc": "2026-01-15T09:45:00Z", "vza": 5.2, "vaa": 103.0, "srf": "sentinel_2a-msi-4"}
    ds = eosim.pics(site, [row], progress=False)
    assert ds.sizes["acquisition"] == 1
    r = float(ds.reflectance[0])
    assert 0.05 < r < 1.0, r


@pytest.mark.parametrize("name,d,pattern", KEYS, ids=[k[0] for k in KEYS])
def test_simulate_check_names_the_same_key(name, d, pattern, simulate, tmp_path):
    import subprocess

    f = tmp_path / "bad.toml"
    f.write_text(eosim._native.dict_to_toml(d))
    p = subprocess.run([str(simulate), "check", str(f)], capture_output=True, text=True)
    assert p.returncode == 2, p.stderr
    import re

    assert re.search(pattern, p.stderr), p.stderr


def test_run_spp_fills_measures_without_one():
    d = copy.deepcopy(RAYLEIGH)
    for m in d["measures"]:
        del m["spp"]
    with pytest.raises(eosim.ConfigError, match=r"measures\[0\]\.spp.*spp=N"):
        eosim.load(d)
    assert eosim.load(d, spp=50).measures == ["toa_pp", "flux"]


def test_eradiate_style_input():
    # One measure table instead of a list, tuples and ranges where lists go, a scalar wavelength.
    d = copy.deepcopy(RAYLEIGH)
    d["measures"] = dict(d["measures"][0], zeniths=range(-60, 61, 60))
    d["spectral"]["wavelengths"] = 550.0
    d["illumination"]["zenith"] = 30.0
    exp = eosim.load(d, spp=20)
    assert exp.measures == ["toa_pp"] and exp.wavelengths == [550.0]
    d["measures"]["zeniths"] = (-30.0, 0.0, 30.0)
    assert eosim.load(d, spp=20).measures == ["toa_pp"]


def test_signed_zenith_and_per_measure_access():
    import matplotlib

    matplotlib.use("Agg")
    ds = eosim.run(RAYLEIGH, spp=200, progress=False)
    # hplane zeniths [-60, 0, 60] come back signed, in the order given; the flux has none.
    np.testing.assert_array_equal(ds.zenith.values[:3], [-60.0, 0.0, 60.0])
    assert np.isnan(ds.zenith.values[3])
    ds.brf.sel(wavelength=550.0).plot(x="zenith")  # the principal plane, unfolded
    pp = ds.eosim.measure("toa_pp")
    assert pp.brf.dims == ("wavelength", "zenith") and pp.sizes["zenith"] == 3
    assert str(pp.measure_type.values) == "mdistant"
    flux = ds.eosim.measure("flux")
    assert flux.sizes["direction"] == 1 and np.isfinite(flux.flux.values).all()
    assert set(ds.eosim.measures()) == {"toa_pp", "flux"}
    with pytest.raises(KeyError, match="toa_pp"):
        ds.eosim.measure("nope")


def test_dict_errors_quote_no_generated_toml():
    with pytest.raises(eosim.ConfigError) as info:
        eosim.load(with_(["measures", 0, "zeniths"], [0.0, "30"]))
    msg = str(info.value)
    assert "measures[0].zeniths" in msg and "(line " not in msg and " | " not in msg, msg
