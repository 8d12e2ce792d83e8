"""Experiments: loading (file, TOML string, dict), properties, runs, errors."""

import copy
import threading
import _thread
import time

import numpy as np
import pytest
import xarray as xr

import eosim
from conftest import RAYLEIGH, REPO


def test_load_from_dict_toml_string_and_file_are_equivalent(tmp_path):
    text = eosim._native.dict_to_toml(RAYLEIGH)
    f = tmp_path / "exp.toml"
    f.write_text(text)
    a = eosim.run(RAYLEIGH, progress=False)
    b = eosim.run(text, progress=False)
    c = eosim.run(f, progress=False)
    d = eosim.Experiment.from_toml(text).run(progress=False)
    e = eosim.Experiment.from_dict(RAYLEIGH).run(progress=False)
    g = eosim.Experiment.from_file(f).run(progress=False)
    for x in (b, c, d, e, g):
        # Same data, coordinates and variable attributes; only `history` names the source.
        xr.testing.assert_equal(a, x)
        assert a.attrs["experiment"] == x.attrs["experiment"] == text
    assert a.attrs["history"] == "created by `simulate run <dict>`"
    assert c.attrs["history"] == f"created by `simulate run {f}`"


def test_toml_round_trip_of_dicts():
    text = eosim._native.dict_to_toml(RAYLEIGH)
    assert eosim._native.toml_to_dict(text, "<string>") == RAYLEIGH
    # numpy values and None (an absent key) are accepted
    d = copy.deepcopy(RAYLEIGH)
    d["spectral"]["wavelengths"] = np.array([450.0, 550.0])
    d["seed"] = np.int64(3)
    d["polarized"] = None
    assert eosim._native.toml_to_dict(eosim._native.dict_to_toml(d), "x") == RAYLEIGH


def test_properties():
    exp = eosim.load(RAYLEIGH, spp=100)
    assert exp.wavelengths == [450.0, 550.0]
    assert exp.measures == ["toa_pp", "flux"]
    assert exp.seed == 3
    assert str(exp.path) == "<dict>"
    assert "[atmosphere]" in exp.text
    m = exp.memory()
    assert m["total"] == m["results"] + m["scene"] and m["results"] > 0
    assert "toa_pp" in repr(exp)


def test_spp_override():
    ds = eosim.run(RAYLEIGH, spp=100, progress=False)
    assert (ds.n_samples == 100).all()


def test_variables_units_and_coordinates():
    ds = eosim.run(RAYLEIGH, progress=False)
    assert ds.wavelength.attrs["units"] == "nm"
    assert ds.brf.dims == ("wavelength", "direction")
    assert set(["vza", "vaa"]) <= set(ds.coords)
    assert ds.attrs["seed"] == 3 and ds.attrs["Conventions"] == "CF-1.10"
    pp = ds.isel(direction=(ds.direction_measure_id == "toa_pp").values)
    assert pp.sizes["direction"] == 3
    assert np.all(pp.brf > 0) and np.all(pp.brf_stderr > 0)


def test_threads_do_not_change_results():
    exp = eosim.load(RAYLEIGH)
    one = exp.run(threads=1, progress=False)
    two = exp.run(threads=2, progress=False)
    xr.testing.assert_identical(one, two)
    with pytest.raises(ValueError, match="threads"):
        exp.run(threads=0, progress=False)


def test_progress_callback_and_text():
    calls = []
    eosim.run(RAYLEIGH, progress=lambda done, total: calls.append((done, total)))
    assert calls and calls[-1][0] == calls[-1][1] > 0
    assert all(b == calls[0][1] for _, b in calls)
    eosim.run(RAYLEIGH, spp=10, progress=True)  # tqdm (or text) bar, closed at the end


def test_output_writes_the_cli_products(tmp_path):
    ds = eosim.run(RAYLEIGH, progress=False, output=tmp_path / "out")
    names = sorted(p.name for p in (tmp_path / "out").iterdir() if not p.name.startswith("."))
    assert names == ["results.csv", "results.nc"]
    xr.testing.assert_identical(ds.drop_vars("zenith"),
                                xr.open_dataset(tmp_path / "out" / "results.nc", decode_coords="all"))


def test_config_errors_name_the_key_path():
    bad = copy.deepcopy(RAYLEIGH)
    bad["atmosphere"]["single_scattering_albedo"] = 1.5
    with pytest.raises(eosim.ConfigError, match=r"<dict>.*atmosphere\.single_scattering_albedo"):
        eosim.load(bad)
    bad = copy.deepcopy(RAYLEIGH)
    bad["measures"][0]["spp"] = "many"
    with pytest.raises(eosim.ConfigError, match=r"measures\[0\]"):
        eosim.load(bad)
    bad = copy.deepcopy(RAYLEIGH)
    bad["surface"]["reflectanse"] = 0.2
    with pytest.raises(eosim.ConfigError, match="reflectanse"):
        eosim.load(bad)
    with pytest.raises(eosim.ConfigError, match="<string>"):
        eosim.load("mode = \n")
    with pytest.raises(eosim.ConfigError, match="no_such_file.toml"):
        eosim.load("no_such_file.toml")
    # ConfigError is a ValueError
    assert issubclass(eosim.ConfigError, ValueError)


def test_python_values_without_toml_form_raise_type_errors():
    bad = copy.deepcopy(RAYLEIGH)
    bad["surface"]["reflectance"] = object()
    with pytest.raises(TypeError, match=r"surface\.reflectance"):
        eosim.load(bad)
    with pytest.raises(TypeError, match="keys must be strings"):
        eosim.load({1: 2})


def test_missing_input_file_is_named(tmp_path):
    bad = copy.deepcopy(RAYLEIGH)
    bad["atmosphere"]["phase"] = {"type": "tabulated", "file": "nowhere.cdf"}
    with pytest.raises(eosim.ConfigError, match="nowhere.cdf"):
        eosim.load(bad, base_dir=tmp_path)


def _long():
    d = copy.deepcopy(RAYLEIGH)
    for m in d["measures"]:
        m["spp"] = 2_000_000_000
    return d


def test_ctrl_c_interrupts_a_run(sigint):
    exp = eosim.load(_long())
    timer = threading.Timer(0.5, _thread.interrupt_main)
    timer.start()
    t0 = time.perf_counter()
    with pytest.raises(KeyboardInterrupt):
        exp.run(progress=False)
    timer.cancel()
    # the package is usable afterwards
    assert eosim.run(RAYLEIGH, spp=10, progress=False).brf.size > 0
    assert time.perf_counter() - t0 < 600  # it returned (no time limit on speed)


def test_the_gil_is_released_during_runs(sigint):
    exp = eosim.load(_long())
    ticks = []
    stop = threading.Event()

    def other():
        while not stop.is_set():
            ticks.append(1)
            time.sleep(0.01)

    def interrupt():
        time.sleep(0.5)
        stop.set()
        _thread.interrupt_main()

    t = threading.Thread(target=other)
    t.start()
    threading.Thread(target=interrupt).start()
    with pytest.raises(KeyboardInterrupt):
        exp.run(progress=False)
    t.join()
    assert len(ticks) > 5  # the other Python thread ran while the run held no GIL


def test_example_file_runs_from_its_folder():
    ds = eosim.run(REPO / "examples" / "rayleigh_lambertian.toml", spp=200, progress=False)
    assert ds.attrs["history"].endswith("rayleigh_lambertian.toml`")


def test_read_toml_and_runs_write_no_files(tmp_path, monkeypatch):
    d = eosim.read_toml(REPO / "examples" / "rayleigh_lambertian.toml")
    assert d["spectral"]["wavelengths"] == [550.0]
    assert eosim.read_toml(d) == d and eosim.read_toml(d) is not d
    # Nothing is written: not in the current folder, not in the temporary folder.
    (tmp_path / "cwd").mkdir()
    (tmp_path / "tmp").mkdir()
    monkeypatch.chdir(tmp_path / "cwd")
    monkeypatch.setenv("TMPDIR", str(tmp_path / "tmp"))
    eosim.run(d, spp=100, progress=False, base_dir=REPO / "examples")
    assert not any((tmp_path / "cwd").iterdir()) and not any((tmp_path / "tmp").iterdir())


def test_lidar_measures_come_back_in_the_dataset(tmp_path):
    # The flat-ground lidar case A1 (validation/lidar): its waveform, whole returns and
    # GEDI-like metrics come back as variables, and the CSV products are written on request.
    exp = eosim.load(REPO / "validation" / "lidar" / "A1.toml", spp=20000)
    assert exp.measures == ["A1"]
    ds = exp.run(progress=False, output=tmp_path / "out")
    e = ds["A1_energy"]
    assert e.dims == ("A1_shot", "A1_part", "A1_bin")
    assert ds["A1_height_m"].sizes["A1_bin"] == 81
    total = ds["A1_total"].values[0, 0]
    assert abs(total - 0.3) < 1e-3
    assert abs(float(ds["A1_ground_m"].values[0])) < 1e-3
    assert (tmp_path / "out" / "A1_waveform.csv").is_file()
    assert (tmp_path / "out" / "A1_metrics.csv").is_file()
