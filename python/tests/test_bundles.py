"""Scene bundles: built from a region dict, opened and inspected; errors."""

import pytest

import eosim
from conftest import REPO


def test_build_and_open(grenoble_bundle):
    b = grenoble_bundle
    assert b.crs.startswith("+proj=tmerc")
    assert b.extent["lon_lat_bbox"] == [5.70, 45.15, 5.76, 45.20]
    assert b.extent["max"][0] > 2000 and b.extent["min"][0] < -2000
    names = [m["name"] for m in b.materials]
    assert "crop" in names and "forest_floor" in names
    assert b.memory["disk_bytes"] > 0
    assert b.memory["flattened_triangles"] >= b.memory["instanced_triangles"] > 0
    assert "materials (" in str(b) and "extent:" in str(b)
    again = eosim.open_bundle(b.path)
    assert again.manifest == b.manifest


def test_existing_output_is_refused_without_force(grenoble_bundle):
    region = eosim.read_toml(REPO / "examples" / "grenoble" / "region.toml")
    region["area"]["bbox"] = [5.70, 45.15, 5.76, 45.20]
    with pytest.raises(eosim.SimulationError, match="exists"):
        eosim.build_bundle(region, grenoble_bundle.path, base_dir=REPO / "examples" / "grenoble")


def test_region_errors_name_the_key(tmp_path):
    with pytest.raises(eosim.ConfigError, match="area"):
        eosim.build_bundle({"seed": 1, "area": {"bbox": [1.0, 2.0]}}, tmp_path / "b")


def test_open_missing_bundle(tmp_path):
    with pytest.raises(eosim.SimulationError, match="manifest"):
        eosim.open_bundle(tmp_path)
