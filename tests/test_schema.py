"""The one TOML schema checker: every problem is one line naming file, table and key."""

import pytest

from lsadphoto._schema import ArrayOf, Key, Table, Variants, read_toml, validate
from lsadphoto.errors import BadInputError

SCHEMA = Table({
    "id": Key(str, required=True),
    "sensor": Table({"width_mm": Key(float, minimum=0, exclusive=True), "width_px": Key(int, minimum=1)}),
    "vignetting": Table({"model": Key(str, default="none", choices=("none", "polynomial")),
                         "coefficients": Key(list, items=float, length=(0, 1, 2, 3), default=[])}),
    "lens_model": Variants("model", {"pinhole": Table({"focal_length_mm": Key(float, minimum=0, exclusive=True)}),
                                     "fisheye-ideal": Table({"fov_deg": Key(float, maximum=360)})},
                           default="pinhole"),
    "luminaire": ArrayOf(Table({"file": Key(str, required=True)})),
    "provenance": Table(open=True),
})


def check(data):
    return validate(data, SCHEMA, source="cam.toml")


def test_defaults_filled_and_ints_accepted_as_floats():
    out = check({"id": "c", "sensor": {"width_mm": 23}, "vignetting": {}})
    assert out["sensor"]["width_mm"] == 23.0 and isinstance(out["sensor"]["width_mm"], float)
    assert out["vignetting"] == {"model": "none", "coefficients": []}


@pytest.mark.parametrize("data, message", [
    ({"id": "c", "vignettng": {}}, "cam.toml: unknown key 'vignettng' (did you mean 'vignetting'?)"),
    ({"id": "c", "sensor": {"widht_mm": 1.0}}, "cam.toml: [sensor] unknown key 'widht_mm' (did you mean 'width_mm'?)"),
    ({"sensor": {}}, "cam.toml: missing required key 'id'"),
    ({"id": "c", "sensor": {"width_px": "640"}}, "cam.toml: sensor.width_px must be an integer, got '640'"),
    ({"id": "c", "sensor": {"width_px": True}}, "cam.toml: sensor.width_px must be an integer, got True"),
    ({"id": "c", "sensor": {"width_mm": 0}}, "cam.toml: sensor.width_mm must be > 0, got 0.0"),
    ({"id": "c", "sensor": {"width_mm": float("inf")}}, "cam.toml: sensor.width_mm must be finite"),
    ({"id": "c", "vignetting": {"model": "poly"}}, "cam.toml: vignetting.model must be one of 'none', 'polynomial'"),
    ({"id": "c", "vignetting": {"coefficients": [1.0] * 50}}, "vignetting.coefficients must have 0 or 1 or 2 or 3 elements, got 50"),
    ({"id": "c", "vignetting": {"coefficients": ["a"]}}, "vignetting.coefficients[0] must be a number, got 'a'"),
    ({"id": "c", "lens_model": {"model": "fisheye-ideal", "focal_length_mm": 8.0}}, "[lens_model] unknown key 'focal_length_mm'"),
    ({"id": "c", "lens_model": {"model": "banana"}}, "lens_model.model must be one of 'pinhole', 'fisheye-ideal', got 'banana'"),
    ({"id": "c", "luminaire": {"file": "a.ies"}}, "luminaire must be an array of tables"),
    ({"id": "c", "luminaire": [{}]}, "cam.toml: [luminaire[0]] missing required key 'file'"),
    ({"id": "c", "sensor": 3}, "sensor must be a table, got 3"),
])
def test_each_problem_is_one_line_naming_the_key(data, message):
    with pytest.raises(BadInputError) as info:
        check(data)
    text = str(info.value)
    assert message in text and "\n" not in text


def test_open_tables_and_variants_pass_their_keys():
    out = check({"id": "c", "provenance": {"anything": "x"}, "lens_model": {"model": "fisheye-ideal", "fov_deg": 180}})
    assert out["provenance"] == {"anything": "x"}
    assert out["lens_model"] == {"model": "fisheye-ideal", "fov_deg": 180.0}
    assert check({"id": "c", "lens_model": {}})["lens_model"] == {"model": "pinhole"}


def test_read_toml_reports_syntax_and_encoding(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("id = \n")
    with pytest.raises(BadInputError, match=r"bad.toml: not a valid TOML camera profile"):
        read_toml(bad, SCHEMA, what="camera profile")
    latin = tmp_path / "latin.toml"
    latin.write_bytes(b'id = "\xe9"\n')
    with pytest.raises(BadInputError, match="not UTF-8"):
        read_toml(latin, SCHEMA, what="camera profile")
    good = tmp_path / "good.toml"
    good.write_text('id = "c"\n[sensor]\nwidth_px = 640\n')
    assert read_toml(good, SCHEMA)["sensor"] == {"width_px": 640}


def test_map_of_named_tables():
    from lsadphoto._schema import MapOf

    schema = Table({"materials": MapOf(Table({"reflectance": Key(float, required=True, minimum=0)}))})
    out = validate({"materials": {"wall": {"reflectance": 1}}}, schema, source="s.toml")
    assert out == {"materials": {"wall": {"reflectance": 1.0}}}
    with pytest.raises(BadInputError, match=r"s.toml: \[materials.wall\] unknown key 'reflectence'"):
        validate({"materials": {"wall": {"reflectence": 0.5}}}, schema, source="s.toml")
    with pytest.raises(BadInputError, match="materials must be a table of named entries"):
        validate({"materials": [1]}, schema, source="s.toml")
