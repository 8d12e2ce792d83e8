"""``eosim.keys``: the key tables of the experiment file, parsed from the package's copy of
``docs/experiment.md`` (one source for the documentation and the Python help)."""

import re

import pytest

import eosim
from conftest import REPO
from eosim import _keys

PACKAGED = REPO / "python" / "eosim" / "data" / "experiment.md"
DOCS = REPO / "docs" / "experiment.md"


def test_the_packaged_reference_is_docs_experiment_md():
    assert PACKAGED.read_bytes() == DOCS.read_bytes(), (
        "python/eosim/data/experiment.md differs from docs/experiment.md: "
        "run `bash scripts/sync-python-docs.sh` and commit the copy")


def test_every_table_of_the_reference_parses():
    sections, problems = _keys._parse(DOCS.read_text(encoding="utf-8"))
    assert not problems, "docs/experiment.md:\n" + "\n".join(problems)
    # Every key or type table of the file lands in a section, row for row.
    rows = 0
    lines = DOCS.read_text(encoding="utf-8").splitlines()
    fence = False
    for i, line in enumerate(lines):
        if line.lstrip().startswith("```"):
            fence = not fence
        if fence or not re.match(r"\| (key|`type`) \|", line):
            continue
        if i + 1 >= len(lines) or not lines[i + 1].startswith("|---"):
            continue  # a row, not a header
        j = i + 2
        while j < len(lines) and lines[j].startswith("|"):
            rows += 1
            j += 1
    assert rows == sum(len(s.rows) for s in sections.values())


def test_sections_named_after_the_file():
    names = [s["section"] for s in eosim.keys()]
    for n in ("top_level", "spectral", "geometry", "atmosphere.homogeneous",
              "atmosphere.molecular", "atmosphere.particle_layers", "surface", "scene.bundle",
              "illumination", "illumination.moon", "lights", "measures", "measures.mdistant",
              "measures.ortho", "measures.radiancemeter", "measures.distant_flux",
              "measures.hdrf", "measures.lidar", "integrator"):
        assert n in names, n
    assert len(set(names)) == len(names)


def test_key_records_with_types_units_and_defaults():
    spectral = {k["key"]: k for k in eosim.keys("spectral")}
    assert spectral["wavelengths"]["unit"] == "nm"
    assert spectral["wavelength_step"]["default"] == "5.0"
    geometry = {k["key"]: k for k in eosim.keys("geometry")}
    assert geometry["toa_altitude"] == {
        "key": "toa_altitude", "type": "number", "unit": "km", "default": "100.0",
        "meaning": "top of the atmosphere"}
    zenith = [k for k in eosim.keys("illumination") if k["key"] == "zenith"][0]
    assert zenith["unit"] == "deg" and zenith["default"].startswith("required")
    ortho = {k["key"] for k in eosim.keys("measures.ortho")}
    assert {"pixel_size_m", "window_m", "spp"} <= ortho
    lidar = {k["key"]: k for k in eosim.keys("measures.lidar")}
    assert lidar["pulse_energy_j"]["unit"] == "J"
    # Tables without a unit column still give every field.
    integrator = eosim.keys("integrator")
    assert all(list(k) == ["key", "type", "unit", "default", "meaning"] for k in integrator)
    assert {k["key"]: k for k in integrator}["sampler"]["unit"] is None
    # Markdown is gone: no backticks, escaped pipes restored.
    canopy = {k["key"]: k for k in eosim.keys("scene.canopy")}
    assert "`" not in canopy["padding"]["meaning"] and "|i|" in canopy["padding"]["meaning"]


def test_tables_of_types():
    surface = {k["type"]: k for k in eosim.keys("surface")}
    assert '"rpv"' in surface and "rho_0" in surface['"rpv"']["keys"]
    solvers = eosim.keys("scene.radiometry_solvers")
    # Continuation rows (more keys of the type above) carry their type.
    assert [k["keys"] for k in solvers if k["type"] == '"generic"'] == [
        "first_bounce_samples", "decay", "max_generations"]


def test_names_are_forgiving():
    assert eosim.keys("[[measures]]") == eosim.keys("measures")
    assert eosim.keys(" [Spectral] ") == eosim.keys("spectral")
    atmosphere = eosim.keys("atmosphere")  # a group: lists its sections
    assert [s["section"] for s in atmosphere][:2] == ["atmosphere.homogeneous",
                                                      "atmosphere.layered"]
    assert all(s["section"].startswith("atmosphere.") for s in atmosphere)


@pytest.mark.parametrize("query,suggested", [
    ("measures.orto", "measures.ortho"),
    ("measures.lidr", "measures.lidar"),
    ("mesures.ortho", "measures.ortho"),
    ("ortho", "measures.ortho"),
    ("spectal", "spectral"),
    ("atmosphere.phase", "atmosphere.phase_tables"),
    ("scene.solvers", "scene.radiometry_solvers"),
])
def test_misspelt_sections_suggest_the_close_match(query, suggested):
    with pytest.raises(ValueError, match=re.escape(f"did you mean '{suggested}'")) as info:
        eosim.keys(query)
    # ... and list every section.
    assert "measures.lidar" in str(info.value) and "integrator" in str(info.value)


def test_unknown_sections_and_bad_arguments():
    with pytest.raises(ValueError, match=r"unknown section 'measures\.camera'\. Sections: top_level"):
        eosim.keys("measures.camera")
    with pytest.raises(TypeError, match="section must be a string"):
        eosim.keys(3)


def test_shown_as_a_table():
    text = repr(eosim.keys("spectral"))
    assert text.splitlines()[0] == "spectral: the [spectral] table"
    assert "  wavelengths (list of numbers > 0 (one number: a list of one); unit nm)" in text
    assert str(eosim.keys("spectral")) == text
    listing = repr(eosim.keys())
    assert re.search(r"^  measures\.ortho +\d+ keys  type = \"ortho\"", listing, re.M), listing
    md = eosim.keys("measures.hdrf")._repr_markdown_()
    assert md.splitlines()[2] == "| key | type | unit | default | meaning |"


def test_the_parser_reports_broken_tables():
    text = "\n".join([
        "## `[x]`", "", "| key | type | unit | default | meaning |", "|---|---|---|---|---|",
        "| `a` | number | m | `1` | an a |", "", "| `b` | number | m | `2` | a b, cut off |",
        "| `c` | number |", ""])
    sections, problems = _keys._parse(text)
    assert [r["key"] for r in sections["x"].rows] == ["a"]
    assert any("without a header" in p for p in problems), problems
