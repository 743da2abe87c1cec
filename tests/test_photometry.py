"""Photometric file readers (lsadphoto.solver.photometry) against independent references.

References used here, none of them the reader itself:

* analytic distributions written as tiny files: an isotropic lower hemisphere
  (Φ = 2π·I0) and a Lambertian down-light I0·cos γ (Φ = π·I0);
* the same distribution written with every symmetry of LM-63 / EULUMDAT and as a full
  0–360° table, and as IES and as LDT (cross-format);
* the real files of ../shared/realdata/photometry (written by others; see its README):
  their numbers are read back by a separate, naive tokeniser in this file, and their stated
  lamp flux × light output ratio (LDT lines 23 and 26c) is compared with the integral.
"""

import math
import re

import numpy as np
import pytest

from lsadphoto.errors import BadInputError, UnsupportedFileError
from lsadphoto.solver.photometry import (
    Photometry,
    read_eulumdat,
    read_ies,
    read_photometry,
)

from .conftest import realdata

#: Round-off tolerance (relative) for results that are exact in exact arithmetic.
EXACT = 1e-12

REAL_IES = (
    "radiance_mgflib_examp1.ies",
    "eulumdatrs_Indoor_60W_120G_5300LM_5000K_OVNI.ies",
    "eulumdatrs_MAXWELL-8-T4_MEASURED_IESNA.ies",
)
REAL_LDT = (
    "acrux_452lm.ldt",
    "alya_359lm.ldt",
    "biolux_dn150.ldt",
    "eulumdatrs_4058075580664_FL_MAX_LUM_1200W_757_SYM_10_WAL.ldt",
    "eulumdatrs_floor_uplight.ldt",
    "eulumdatrs_fluorescent_luminaire.ldt",
    "sensor.ldt",
    "variant2_sensor_wide.ldt",
    "wide_luminaire.ldt",
)


# ------------------------------------------------------------------------------------------
# Writers of synthetic files (kept deliberately simple and independent of the reader)
# ------------------------------------------------------------------------------------------


def _fmt(x):
    return repr(float(x))


def _lines_of(values, per_line):
    values = [_fmt(v) for v in np.ravel(values)]
    return [" ".join(values[k:k + per_line]) for k in range(0, len(values), per_line)]


def write_ies(path, gamma, c, candela, *, first_line="IES:LM-63-2019", keywords=("[TEST] synthetic",),
              n_lamps=1, lumens=-1, multiplier=1.0, ptype=1, units=2, opening=(0, 0, 0),
              ballast=1.0, second=1.0, watts=10.0, tilt="NONE", tilt_block=None, per_line=7,
              sep=" "):
    """An LM-63 file; candela has shape (len(c), len(gamma)); numbers wrap every per_line."""
    lines = ([first_line] if first_line else []) + list(keywords) + [f"TILT={tilt}"]
    if tilt_block is not None:
        lines += tilt_block
    lines.append(sep.join(_fmt(v) for v in (n_lamps, lumens, multiplier, len(gamma), len(c), ptype, units,
                                            *opening)))
    lines.append(f"{_fmt(ballast)} {_fmt(second)} {_fmt(watts)}")
    lines += _lines_of(gamma, per_line) + _lines_of(c, per_line)
    for row in np.atleast_2d(candela):
        lines += _lines_of(row, per_line)
    path.write_text("\r\n".join(lines) + "\r\n")
    return path


def write_ldt(path, c_list, gamma, stored, *, isym, lamp_sets=((1, 1000.0),), lorl=100.0, dff=100.0,
              conversion=1.0, luminous=(0.0, 0.0), heights=(0.0, 0.0, 0.0, 0.0), ityp=3):
    """A EULUMDAT file; ``stored`` [cd/klm] holds the planes the symmetry indicator stores."""
    dc = c_list[1] - c_list[0] if len(c_list) > 1 else 0
    lines = ["synthetic", str(ityp), str(isym), str(len(c_list)), _fmt(dc), str(len(gamma)),
             _fmt(gamma[1] - gamma[0]), "report", "name", "number", "file.ldt", "date",
             "100", "50", "20", _fmt(luminous[0]), _fmt(luminous[1]), *(_fmt(h) for h in heights),
             _fmt(dff), _fmt(lorl), _fmt(conversion), "0", str(len(lamp_sets))]
    for n_lamps, flux in lamp_sets:
        lines += [str(n_lamps), "LED", _fmt(flux), "3000K", "80", "10"]
    lines += ["0.5"] * 10
    lines += [_fmt(v) for v in c_list] + [_fmt(v) for v in gamma]
    lines += [_fmt(v) for v in np.ravel(stored)]
    path.write_text("\n".join(lines) + "\n")
    return path


def sample(function, c_deg, gamma_deg):
    """(n_c, n_gamma) table of function(C [rad], γ [rad])."""
    c, g = np.meshgrid(np.radians(c_deg), np.radians(gamma_deg), indexing="ij")
    return function(c, g)


def asymmetric(c, g):
    """A smooth distribution with no lateral symmetry [cd]."""
    return 200 * np.cos(g / 2) ** 2 * (1.5 + 0.3 * np.cos(c) + 0.2 * np.sin(c) + 0.1 * np.cos(2 * c + 0.4))


#: Distributions with each symmetry: I(C) = I(−C) (plane C0–C180), I(C) = I(180°−C)
#: (plane C90–C270), both (quadrant), none in C (rotational).
SYMMETRIC = {
    "rotational": lambda c, g: 300 * np.cos(g / 2) ** 2 + 0 * c,
    "quadrant": lambda c, g: 300 * np.cos(g / 2) ** 2 * (1.2 + 0.5 * np.cos(2 * c)),
    "plane C0-C180": lambda c, g: 300 * np.cos(g / 2) ** 2 * (1.2 + 0.5 * np.cos(c) + 0.2 * np.cos(2 * c)),
    "plane C90-C270": lambda c, g: 300 * np.cos(g / 2) ** 2 * (1.2 + 0.5 * np.sin(c) + 0.2 * np.cos(2 * c)),
}

GAMMA = np.arange(0.0, 181.0, 10.0)
FULL_C = np.arange(0.0, 361.0, 15.0)


def random_directions(n=500, seed=1):
    rng = np.random.default_rng(seed)
    return rng.uniform(-2 * np.pi, 4 * np.pi, n), np.arccos(rng.uniform(-1, 1, n))


def relative_sampling_error(photometry):
    """Spread between two second-order rules on the same samples, relative to the flux.

    The reader integrates the bilinear interpolant exactly; the trapezoid rule on I·sin γ
    at the sampled angles is another O(Δγ²) estimate of the same integral. Their
    difference is of the size of the error either makes against the true (unsampled)
    distribution, so it is the angular-sampling uncertainty of a file's integrated flux.
    """
    g = np.radians(photometry.gamma_angles)
    c = np.radians(photometry.c_angles)
    trapezoid = np.trapezoid(np.trapezoid(photometry.candela * np.sin(g), g, axis=1), c)
    return abs(trapezoid - photometry.luminous_flux) / photometry.luminous_flux


# ------------------------------------------------------------------------------------------
# Analytic references
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("step", [2.5, 5.0, 10.0, 22.5])
def test_isotropic_lower_hemisphere_flux_is_2pi_i0(tmp_path, step):
    # I0 constant on 0..90°: the interpolant is exactly the distribution, and the reader's
    # closed-form γ weights make the integral exact up to round-off.
    i0 = 250.0
    gamma = np.arange(0.0, 90.0 + step / 2, step)
    ies = read_ies(write_ies(tmp_path / "iso.ies", gamma, [0.0], np.full((1, gamma.size), i0)))
    ldt = read_eulumdat(write_ldt(tmp_path / "iso.ldt", np.arange(0.0, 360.0, 30.0), gamma,
                                  np.full(gamma.size, i0), isym=1))
    for p in (ies, ldt):
        assert p.luminous_flux == pytest.approx(2 * math.pi * i0, rel=EXACT)
        assert p.zonal_flux(math.pi / 2, math.pi) == 0.0
        assert float(p.intensity(0.3, math.radians(120.0))) == 0.0  # beyond the last γ


@pytest.mark.parametrize("step", [1.0, 5.0, 10.0])
def test_lambertian_downlight_flux_is_pi_i0(tmp_path, step):
    # I = I0 cos γ sampled every Δ and interpolated linearly: the interpolant lies below
    # cos γ by Δ²/12·cos γ on average over each segment (cos'' = −cos), so the flux is
    # π·I0·(1 − Δ²/12 + O(Δ⁴)). The test checks that predicted error to 2 % of itself.
    i0 = 1000.0
    gamma = np.arange(0.0, 90.0 + step / 2, step)
    values = i0 * np.cos(np.radians(gamma))
    values[-1] = 0.0  # cos 90° exactly
    p = read_ies(write_ies(tmp_path / "lambert.ies", gamma, [0.0, 90.0], np.vstack([values, values])))
    relative_error = p.luminous_flux / (math.pi * i0) - 1
    predicted = -math.radians(step) ** 2 / 12
    assert relative_error == pytest.approx(predicted, rel=0.02)
    assert p.metadata["symmetry"] == "quadrant"


def test_piecewise_linear_distribution_is_integrated_exactly(tmp_path):
    # A distribution linear in γ between samples is its own interpolant: the flux is exact.
    # Reference: ∫_0^{π/2} (1 − 2γ/π) sin γ dγ = 1 − 2/π, times 2π·I0.
    i0 = 400.0
    p = read_ies(write_ies(tmp_path / "tri.ies", [0.0, 90.0], [0.0], [[i0, 0.0]]))
    assert p.luminous_flux == pytest.approx(2 * math.pi * i0 * (1 - 2 / math.pi), rel=EXACT)


# ------------------------------------------------------------------------------------------
# Symmetry: every reduced table reads like the equivalent full table
# ------------------------------------------------------------------------------------------

IES_STORED_C = {
    "rotational": [0.0],
    "quadrant": np.arange(0.0, 91.0, 15.0),
    "plane C0-C180": np.arange(0.0, 181.0, 15.0),
    "plane C90-C270": np.arange(90.0, 271.0, 15.0),
}


@pytest.mark.parametrize("symmetry", sorted(SYMMETRIC))
def test_ies_symmetry_equals_full_table(tmp_path, symmetry):
    function = SYMMETRIC[symmetry]
    stored = IES_STORED_C[symmetry]
    reduced = read_ies(write_ies(tmp_path / "reduced.ies", GAMMA, stored, sample(function, stored, GAMMA)))
    full = read_ies(write_ies(tmp_path / "full.ies", GAMMA, FULL_C, sample(function, FULL_C, GAMMA)))
    assert reduced.metadata["symmetry"] == symmetry
    assert full.metadata["symmetry"] == "none"
    c, g = random_directions()
    np.testing.assert_allclose(reduced.intensity(c, g), full.intensity(c, g), rtol=EXACT, atol=1e-9)
    assert reduced.luminous_flux == pytest.approx(full.luminous_flux, rel=EXACT)
    if symmetry != "rotational":
        np.testing.assert_array_equal(reduced.c_angles, FULL_C)
        np.testing.assert_allclose(reduced.candela, full.candela, rtol=EXACT)


def test_ies_bilateral_expansion_mirrors_planes(tmp_path):
    stored = IES_STORED_C["plane C0-C180"]
    table = sample(SYMMETRIC["plane C0-C180"], stored, GAMMA)
    p = read_ies(write_ies(tmp_path / "bi.ies", GAMMA, stored, table))
    for k, angle in enumerate(p.c_angles):
        mirror = np.flatnonzero(p.c_angles == (360.0 - angle) % 360.0)[0]
        np.testing.assert_array_equal(p.candela[k], p.candela[mirror])  # I(C) = I(360° − C)


LDT_STORED = {  # Isym → indices of the stored planes in a 24-plane list (Stockmar 1990)
    1: [0],
    2: list(range(13)),
    3: [18, 19, 20, 21, 22, 23, 0, 1, 2, 3, 4, 5, 6],  # C270 … C345, C0 … C90
    4: list(range(7)),
}
LDT_FUNCTION = {1: "rotational", 2: "plane C0-C180", 3: "plane C90-C270", 4: "quadrant"}


@pytest.mark.parametrize("isym", [1, 2, 3, 4])
def test_ldt_symmetry_equals_full_table(tmp_path, isym):
    function = SYMMETRIC[LDT_FUNCTION[isym]]
    c_list = np.arange(0.0, 360.0, 15.0)
    table = sample(function, c_list, GAMMA)
    reduced = read_eulumdat(write_ldt(tmp_path / "r.ldt", c_list, GAMMA, table[LDT_STORED[isym]], isym=isym))
    full = read_eulumdat(write_ldt(tmp_path / "f.ldt", c_list, GAMMA, table, isym=0))
    c, g = random_directions()
    np.testing.assert_allclose(reduced.intensity(c, g), full.intensity(c, g), rtol=EXACT, atol=1e-9)
    assert reduced.luminous_flux == pytest.approx(full.luminous_flux, rel=EXACT)


def test_ldt_isym3_order_is_c270_through_c0_to_c90(tmp_path):
    # A plane-C90–C270 distribution bright towards +y (C = 90°): if the reader took the
    # stored planes as C90 … C270 instead, the bright side would come out at C = 270°.
    c_list = np.arange(0.0, 360.0, 15.0)
    table = sample(SYMMETRIC["plane C90-C270"], c_list, GAMMA)
    p = read_eulumdat(write_ldt(tmp_path / "i3.ldt", c_list, GAMMA, table[LDT_STORED[3]], isym=3))
    assert float(p.intensity(math.pi / 2, 1.0)) > float(p.intensity(3 * math.pi / 2, 1.0))


# ------------------------------------------------------------------------------------------
# Cross-format and conversions
# ------------------------------------------------------------------------------------------


def test_same_distribution_as_ies_and_ldt_reads_identically(tmp_path):
    c_list = np.arange(0.0, 360.0, 15.0)
    table = sample(SYMMETRIC["plane C0-C180"], c_list, GAMMA)
    half = np.arange(13)
    ies = read_ies(write_ies(tmp_path / "x.ies", GAMMA, c_list[half], table[half],
                             opening=(0.2, 0.6, 0.05)))
    # EULUMDAT stores cd/klm: with 2000 lm of lamps, the file's numbers are half the cd.
    ldt = read_eulumdat(write_ldt(tmp_path / "x.ldt", c_list, GAMMA, table[half] / 2, isym=2,
                                  lamp_sets=((1, 2000.0),), luminous=(600.0, 200.0), heights=(50, 50, 50, 50)))
    np.testing.assert_array_equal(ies.c_angles, ldt.c_angles)
    np.testing.assert_array_equal(ies.gamma_angles, ldt.gamma_angles)
    np.testing.assert_allclose(ies.candela, ldt.candela, rtol=EXACT)
    assert ies.luminous_flux == pytest.approx(ldt.luminous_flux, rel=EXACT)
    c, g = random_directions()
    np.testing.assert_allclose(ies.intensity(c, g), ldt.intensity(c, g), rtol=EXACT)
    np.testing.assert_allclose(ies.luminance(c, g), ldt.luminance(c, g), rtol=EXACT)
    assert (ies.width, ies.length, ies.height) == pytest.approx((ldt.width, ldt.length, ldt.height))


def test_ldt_lamp_flux_sets_conversion_factor_and_absolute_flag(tmp_path):
    gamma, c_list = np.array([0.0, 90.0]), np.arange(0.0, 360.0, 90.0)
    stored = np.array([100.0, 0.0])
    base = read_eulumdat(write_ldt(tmp_path / "a.ldt", c_list, gamma, stored, isym=1))
    np.testing.assert_array_equal(base.candela[:, 0], 100.0)
    # 2 lamps with a *total* flux (line 26c) of 3000 lm: ×3, the lamp count is not applied.
    two = read_eulumdat(write_ldt(tmp_path / "b.ldt", c_list, gamma, stored, isym=1,
                                  lamp_sets=((2, 3000.0), (1, 9999.0)), conversion=0.5))
    np.testing.assert_allclose(two.candela[:, 0], 100.0 * 3.0 * 0.5, rtol=EXACT)
    assert len(two.metadata["lamp_sets"]) == 2 and not two.metadata["absolute"]
    absolute = read_eulumdat(write_ldt(tmp_path / "c.ldt", c_list, gamma, stored, isym=1,
                                       lamp_sets=((-1, 1000.0),)))
    assert absolute.metadata["absolute"]
    np.testing.assert_array_equal(absolute.candela, base.candela)


def test_ldt_decimal_commas(tmp_path):
    # Some European tools write decimal commas; in EULUMDAT (one value per line) a comma
    # can only be one.
    c_list, gamma = np.arange(0.0, 360.0, 90.0), np.array([0.0, 45.0, 90.0])
    path = write_ldt(tmp_path / "comma.ldt", c_list, gamma, [100.5, 50.25, 0.0], isym=1)
    path.write_text(path.read_text().replace("100.5", "100,5").replace("50.25", "50,25"))
    np.testing.assert_array_equal(read_eulumdat(path).candela[0], [100.5, 50.25, 0.0])


def test_ldt_opening_in_metres_and_circular_convention(tmp_path):
    gamma, c_list = np.array([0.0, 90.0]), np.arange(0.0, 360.0, 90.0)
    rect = read_eulumdat(write_ldt(tmp_path / "r.ldt", c_list, gamma, [100.0, 0.0], isym=1,
                                   luminous=(1170.0, 90.0), heights=(10, 20, 10, 20)))
    assert (rect.length, rect.width, rect.height) == pytest.approx((1.17, 0.09, 0.015))
    disc = read_eulumdat(write_ldt(tmp_path / "d.ldt", c_list, gamma, [100.0, 0.0], isym=1,
                                   luminous=(200.0, 0.0)))
    assert (disc.length, disc.width) == pytest.approx((-0.2, -0.2))


# ------------------------------------------------------------------------------------------
# IES header variants, TILT, types
# ------------------------------------------------------------------------------------------

BASE_GAMMA = np.array([0.0, 30.0, 60.0, 90.0])
BASE_TABLE = np.array([[100.0, 90.0, 50.0, 0.0]])


@pytest.mark.parametrize(("first_line", "fmt", "second", "factor"), [
    (None, "IES LM-63-1986", 0.9, 0.9),              # no version line: 1986 layout, free text
    ("IESNA91", "IES LM-63-1991", 0.9, 0.9),
    ("IESNA:LM-63-1995", "IES LM-63-1995", 0.9, 0.9),  # ballast-lamp photometric factor applied
    ("IESNA:LM-63-2002", "IES LM-63-2002", 0.5, 1.0),  # "future use": not applied
    ("IES:LM-63-2019", "IES LM-63-2019", 1.10001, 1.0),  # file generation type: not applied
])
def test_ies_versions(tmp_path, first_line, fmt, second, factor):
    keywords = ("free text of a 1986 file",) if first_line is None else (
        "[TEST] T1", "[MANUFAC] Acme", "[MORE] second line", "[LUMCAT] X-1", "[_USER] custom")
    p = read_ies(write_ies(tmp_path / "v.ies", BASE_GAMMA, [0.0], BASE_TABLE, first_line=first_line,
                           keywords=keywords, second=second, ballast=0.8, multiplier=2.0, per_line=3))
    assert p.format == fmt
    np.testing.assert_allclose(p.candela[0], BASE_TABLE[0] * 2.0 * 0.8 * factor, rtol=EXACT)
    if first_line is None:
        assert p.metadata["header_lines"] == ["free text of a 1986 file"]
    else:
        assert p.metadata["MANUFAC"] == "Acme\nsecond line"
        assert p.metadata["_USER"] == "custom"
    if fmt == "IES LM-63-2019":
        assert p.metadata["file_generation_type"] == 1.10001


def test_ies_comma_delimiters_and_feet(tmp_path):
    p = read_ies(write_ies(tmp_path / "ft.ies", BASE_GAMMA, [0.0], BASE_TABLE, units=1,
                           opening=(1.0, 2.0, 0.5), sep=","))
    assert (p.width, p.length, p.height) == pytest.approx((0.3048, 0.6096, 0.1524))


def test_ies_tilt_include_is_applied(tmp_path):
    block = ["1", "3", "0 30 90", "1.0 0.8 0.5"]
    path = write_ies(tmp_path / "t.ies", BASE_GAMMA, [0.0], BASE_TABLE, tilt="INCLUDE", tilt_block=block)
    np.testing.assert_allclose(read_ies(path).candela[0], BASE_TABLE[0], rtol=EXACT)
    tilted = read_ies(path, tilt=60.0)  # halfway between 0.8 and 0.5
    np.testing.assert_allclose(tilted.candela[0], BASE_TABLE[0] * 0.65, rtol=EXACT)
    assert tilted.metadata["tilt"]["factors"] == [1.0, 0.8, 0.5]


def test_ies_tilt_file_beside_the_ies_file(tmp_path):
    (tmp_path / "lamp.tlt").write_text("1\n2\n0 90\n1 0.5\n")
    path = write_ies(tmp_path / "t.ies", BASE_GAMMA, [0.0], BASE_TABLE, tilt="lamp.tlt")
    np.testing.assert_allclose(read_ies(path, tilt=45.0).candela[0], BASE_TABLE[0] * 0.75, rtol=EXACT)
    missing = write_ies(tmp_path / "m.ies", BASE_GAMMA, [0.0], BASE_TABLE, tilt="absent.tlt")
    with pytest.raises(UnsupportedFileError, match="absent.tlt"):
        read_ies(missing)


def test_ies_byte_order_mark_and_bad_tilt_option(tmp_path):
    path = write_ies(tmp_path / "bom.ies", BASE_GAMMA, [0.0], BASE_TABLE)
    path.write_bytes(b"\xef\xbb\xbf" + path.read_bytes())
    assert read_ies(path).format == "IES LM-63-2019"
    with pytest.raises(BadInputError, match="tilt") as info:
        read_ies(path, tilt="steep")
    assert not isinstance(info.value, UnsupportedFileError)  # the option is wrong, not the file


def test_ies_full_table_one_step_short_of_360_closes_periodically(tmp_path):
    c = np.arange(0.0, 360.0, 15.0)  # 0 … 345°, no 360° plane
    table = sample(asymmetric, c, GAMMA)
    p = read_ies(write_ies(tmp_path / "345.ies", GAMMA, c, table))
    np.testing.assert_array_equal(p.candela[-1], table[0])
    with pytest.raises(UnsupportedFileError, match="no LM-63 symmetry"):
        read_ies(write_ies(tmp_path / "270.ies", GAMMA, c[:19], table[:19]))  # 0 … 270°


@pytest.mark.parametrize(("ptype", "letter"), [(2, "B"), (3, "A")])
def test_ies_types_a_and_b_are_refused(tmp_path, ptype, letter):
    path = write_ies(tmp_path / "ab.ies", BASE_GAMMA, [0.0], BASE_TABLE, ptype=ptype)
    with pytest.raises(UnsupportedFileError, match=f"type {letter} is not supported"):
        read_ies(path)


def test_ies_upper_hemisphere_only(tmp_path):
    # Type C files may start at γ = 90° (uplights): no light below the horizontal.
    gamma = np.array([90.0, 135.0, 180.0])
    p = read_ies(write_ies(tmp_path / "up.ies", gamma, [0.0], [[0.0, 50.0, 100.0]]))
    assert float(p.intensity(0.0, 0.2)) == 0.0
    assert float(p.intensity(0.0, math.pi)) == 100.0
    assert p.zonal_flux(0.0, math.pi / 2) == 0.0


# ------------------------------------------------------------------------------------------
# Interpolation and luminance
# ------------------------------------------------------------------------------------------


def test_intensity_interpolation_periodicity_nan_and_shapes(tmp_path):
    table = sample(asymmetric, FULL_C, GAMMA)
    p = read_ies(write_ies(tmp_path / "a.ies", GAMMA, FULL_C, table))
    # exact at the samples
    cc, gg = np.meshgrid(np.radians(FULL_C), np.radians(GAMMA), indexing="ij")
    np.testing.assert_array_equal(p.intensity(cc, gg), table)
    # bilinear: the centre of a cell is the mean of its four corners
    centre = p.intensity(np.radians(7.5), np.radians(15.0))
    assert float(centre) == pytest.approx(table[0:2, 1:3].mean(), rel=EXACT)
    # periodic in C, NaN propagates, broadcasting
    c, g = random_directions(50)
    np.testing.assert_allclose(p.intensity(c + 2 * np.pi, g), p.intensity(c, g), rtol=1e-9)
    assert np.isnan(p.intensity(np.nan, 0.1)) and np.isnan(p.intensity(0.1, np.nan))
    assert p.intensity(np.zeros((3, 1)), np.zeros((1, 4))).shape == (3, 4)


def test_luminance_models(tmp_path):
    table = np.full((1, 3), 120.0)
    gamma = np.array([0.0, 45.0, 90.0])
    rect = read_ies(write_ies(tmp_path / "r.ies", gamma, [0.0], table, opening=(0.3, 0.6, 0.1)))
    assert float(rect.luminance(0.0, 0.0)) == pytest.approx(120.0 / (0.3 * 0.6), rel=EXACT)
    # seen horizontally along +x (C = 0): the 0.3 m × 0.1 m end face
    assert float(rect.luminance(0.0, math.pi / 2)) == pytest.approx(120.0 / (0.3 * 0.1), rel=1e-9)
    assert float(rect.luminance(math.pi / 2, math.pi / 2)) == pytest.approx(120.0 / (0.6 * 0.1), rel=1e-9)
    disc = read_ies(write_ies(tmp_path / "d.ies", gamma, [0.0], table, opening=(-0.2, -0.2, 0.0)))
    g = math.radians(45.0)
    assert float(disc.luminance(1.0, g)) == pytest.approx(120.0 / (math.pi * 0.01 * math.cos(g)), rel=1e-9)
    sphere = read_ies(write_ies(tmp_path / "s.ies", gamma, [0.0], table, opening=(-0.2, -0.2, -0.2)))
    assert float(sphere.luminance(2.0, 0.7)) == pytest.approx(120.0 / (math.pi * 0.01), rel=1e-9)
    point = read_ies(write_ies(tmp_path / "p.ies", gamma, [0.0], table))
    assert np.isinf(point.luminance(0.0, 0.0))  # no RuntimeWarning (warnings are errors here)
    assert np.isnan(point.luminance(0.0, math.radians(120.0)))  # 0 cd over 0 m²
    odd = read_ies(write_ies(tmp_path / "o.ies", gamma, [0.0], table, opening=(-0.2, 0.5, -0.1)))
    with pytest.raises(BadInputError, match="not supported by the luminance model"):
        odd.luminance(0.0, 0.0)


def test_zonal_flux_adds_up_and_checks_limits(tmp_path):
    p = read_ies(write_ies(tmp_path / "z.ies", GAMMA, FULL_C, sample(asymmetric, FULL_C, GAMMA)))
    parts = p.zonal_flux(0, 0.3) + p.zonal_flux(0.3, 1.9) + p.zonal_flux(1.9, math.pi)
    assert parts == pytest.approx(p.luminous_flux, rel=EXACT)
    with pytest.raises(BadInputError):
        p.zonal_flux(1.0, 0.5)


def test_photometry_constructor_validates():
    Photometry([0.0, 360.0], [0.0, 90.0], [[1.0, 0.0], [1.0, 0.0]])
    with pytest.raises(BadInputError, match="c_angles"):
        Photometry([0.0, 180.0], [0.0, 90.0], [[1.0, 0.0], [1.0, 0.0]])
    with pytest.raises(BadInputError, match="shape"):
        Photometry([0.0, 360.0], [0.0, 90.0], [[1.0, 0.0]])


# ------------------------------------------------------------------------------------------
# Dispatcher and malformed files
# ------------------------------------------------------------------------------------------


def test_read_photometry_dispatches_by_suffix(tmp_path):
    ies = write_ies(tmp_path / "UPPER.IES", BASE_GAMMA, [0.0], BASE_TABLE)
    assert read_photometry(ies).format == "IES LM-63-2019"
    ldt = write_ldt(tmp_path / "x.LDT", np.arange(0.0, 360.0, 90.0), BASE_GAMMA, BASE_TABLE[0], isym=1)
    assert read_photometry(ldt).format == "EULUMDAT"
    other = tmp_path / "x.txt"
    other.write_text("x")
    with pytest.raises(BadInputError, match=r"valid: \.ies, \.ldt"):
        read_photometry(other)
    with pytest.raises(BadInputError, match="does not exist"):
        read_photometry(tmp_path / "absent.ies")
    with pytest.raises(TypeError):
        read_photometry(ldt, tilt=10.0)  # a wrong option is not a file error


def _good_ies_text():
    return ("IESNA:LM-63-2002\n[TEST] t\nTILT=NONE\n1 -1 1 3 2 1 2 0 0 0\n1 1 10\n0 45 90\n0 180\n"
            "100 80 0\n100 70 0\n")


def _good_ldt_lines(tmp_path):
    path = write_ldt(tmp_path / "good.ldt", np.arange(0.0, 360.0, 90.0), BASE_GAMMA, BASE_TABLE[0], isym=1)
    return path.read_text().split("\n")


IES_BREAKAGES = {
    "empty": ("", "empty"),
    "blank": ("\n \n", "empty"),
    "no TILT": (_good_ies_text().replace("TILT=NONE\n", ""), "TILT"),
    "truncated": (_good_ies_text()[:-12], "truncated"),
    "non-numeric": (_good_ies_text().replace("100 70 0", "100 7O 0"), "non-numeric"),
    "extra values": (_good_ies_text() + "5 5\n", "values after"),
    "fractional count": (_good_ies_text().replace("1 -1 1 3 2", "1 -1 1 3.5 2"), "integer"),
    "bad type": (_good_ies_text().replace("0 0 0\n1 1 10", "0 0 0\n1 1 10").replace(" 2 1 2 ", " 2 7 2 "),
                 "photometric type 7"),
    "bad horizontal range": (_good_ies_text().replace("0 180\n", "0 120\n"), "no LM-63 symmetry"),
    "descending angles": (_good_ies_text().replace("0 45 90", "0 90 45"), "ascending"),
    "negative candela": (_good_ies_text().replace("100 70 0", "100 -70 0"), "negative"),
    "unknown version": ("IESNA:LM-63-2042\n" + _good_ies_text().split("\n", 1)[1], "version"),
    "zero multiplier": (_good_ies_text().replace("1 -1 1 3 2", "1 -1 0 3 2"), "not positive"),
    "type A": (_good_ies_text().replace(" 2 1 2 ", " 2 3 2 "), "type A is not supported"),
}


@pytest.mark.parametrize("case", sorted(IES_BREAKAGES))
def test_malformed_ies_gives_one_line_error(tmp_path, case):
    text, fragment = IES_BREAKAGES[case]
    path = tmp_path / "bad.ies"
    path.write_text(text)
    with pytest.raises(UnsupportedFileError) as info:
        read_ies(path)
    message = str(info.value)
    assert fragment in message and "bad.ies" in message and "\n" not in message


def _ldt_breakages(lines):
    return {
        "truncated header": ("\n".join(lines[:15]), "truncated"),
        "truncated data": ("\n".join(lines[:-3]), "truncated"),
        "isym 7": ("\n".join([lines[0], lines[1], "7", *lines[3:]]), "Isym = 7"),
        "non-numeric Mc": ("\n".join([*lines[:3], "twelve", *lines[4:]]), "line 4"),
        "non-numeric intensity": ("\n".join([*lines[:-3], "abc", *lines[-2:]]), "non-numeric"),
        "extra values": ("\n".join(lines + ["1", "2"]), "values after"),
        "zero lamp flux": ("\n".join([*lines[:28], "0", *lines[29:]]), "lamp flux"),
        "binary": ("\x00\x01\x02garbage", "binary"),
    }


@pytest.mark.parametrize("case", ["truncated header", "truncated data", "isym 7", "non-numeric Mc",
                                  "non-numeric intensity", "extra values", "zero lamp flux", "binary"])
def test_malformed_ldt_gives_one_line_error(tmp_path, case):
    text, fragment = _ldt_breakages(_good_ldt_lines(tmp_path))[case]
    path = tmp_path / "bad.ldt"
    path.write_text(text)
    with pytest.raises(UnsupportedFileError) as info:
        read_eulumdat(path)
    message = str(info.value)
    assert fragment in message and "bad.ldt" in message and "\n" not in message


# ------------------------------------------------------------------------------------------
# Real files written by others (../shared/realdata/photometry)
# ------------------------------------------------------------------------------------------


def _numbers(text):
    """All numeric tokens of a text, by a naive split (independent of the readers)."""
    out = []
    for token in re.split(r"[\s,]+", text):
        try:
            out.append(float(token))
        except ValueError:
            pass
    return out


def _ldt_line(path, number):
    return path.read_text(encoding="latin-1").split("\n")[number - 1].strip()


def _half_unit(text):
    """Half a unit of the last digit written, relative to the number (rounding of a figure)."""
    decimals = len(text.split(".")[1]) if "." in text else 0
    return 0.5 * 10.0**-decimals / float(text)


@pytest.mark.realdata
@pytest.mark.parametrize("name", REAL_IES + REAL_LDT)
def test_real_file_parses(name):
    path = realdata(f"photometry/{name}")
    p = read_photometry(path)
    assert p.c_angles[0] == 0.0 and p.c_angles[-1] == 360.0
    assert p.candela.shape == (p.c_angles.size, p.gamma_angles.size)
    assert np.all(np.isfinite(p.candela)) and p.candela.max() > 0
    assert p.luminous_flux > 0
    expected = {"radiance_mgflib_examp1.ies": "IES LM-63-1995",
                "eulumdatrs_Indoor_60W_120G_5300LM_5000K_OVNI.ies": "IES LM-63-2002",
                "eulumdatrs_MAXWELL-8-T4_MEASURED_IESNA.ies": "IES LM-63-1995"}
    assert p.format == expected.get(name, "EULUMDAT")


@pytest.mark.realdata
@pytest.mark.parametrize("name", REAL_LDT)
def test_real_ldt_values_are_the_files_numbers(name):
    path = realdata(f"photometry/{name}")
    p = read_eulumdat(path)
    meta = p.metadata
    ng = int(_ldt_line(path, 6))
    stored = meta["stored_c_angles"]
    # the intensity table is the last len(stored)·Ng numbers of the file
    values = np.array(_numbers(path.read_text(encoding="latin-1"))[-len(stored) * ng:]).reshape(len(stored), ng)
    scale = float(_ldt_line(path, 29)) / 1000.0 * float(_ldt_line(path, 24))  # lamp set 1 flux, factor
    for row, angle in zip(values, stored):
        k = np.flatnonzero(p.c_angles == angle)[0]
        np.testing.assert_array_equal(p.candela[k], row * scale)
        np.testing.assert_array_equal(p.intensity(np.radians(angle), np.radians(p.gamma_angles)), row * scale)


@pytest.mark.realdata
@pytest.mark.parametrize("name", REAL_IES)
def test_real_ies_values_are_the_files_numbers(name):
    path = realdata(f"photometry/{name}")
    p = read_ies(path)
    text = path.read_text(encoding="latin-1")
    after_tilt = text.split("TILT=NONE", 1)[1]
    numbers = _numbers(after_tilt)
    n_v, n_h = int(numbers[3]), int(numbers[4])
    scale = numbers[2] * numbers[10] * (numbers[11] if "1995" in p.format else 1.0)
    c_stored = numbers[13 + n_v:13 + n_v + n_h]
    table = np.array(numbers[13 + n_v + n_h:]).reshape(n_h, n_v)
    for row, angle in zip(table, c_stored):
        k = np.flatnonzero(p.c_angles == angle)[0]
        np.testing.assert_array_equal(p.candela[k], row * scale)


@pytest.mark.realdata
@pytest.mark.parametrize("name", REAL_LDT)
def test_real_ldt_integrated_flux_matches_lorl_times_lamp_flux(name):
    path = realdata(f"photometry/{name}")
    p = read_eulumdat(path)
    lorl_text, flux_text = _ldt_line(path, 23), _ldt_line(path, 29)
    stated = float(lorl_text) / 100.0 * float(flux_text)
    # Tolerance: the stated figures are rounded (half a unit of their last digit), and the
    # integral of a sampled distribution is uncertain by about the spread between two
    # second-order rules on the same samples (relative_sampling_error); twice that spread
    # covers the difference of quadratures used by the file's author and by us.
    tolerance = _half_unit(lorl_text) + _half_unit(flux_text) + 2 * relative_sampling_error(p)
    assert p.luminous_flux == pytest.approx(stated, rel=tolerance)


@pytest.mark.realdata
@pytest.mark.parametrize("name", REAL_LDT)
def test_real_ldt_downward_flux_fraction(name):
    path = realdata(f"photometry/{name}")
    p = read_eulumdat(path)
    dff_text = _ldt_line(path, 22)
    down = p.zonal_flux(0.0, math.pi / 2) / p.luminous_flux
    g = np.radians(p.gamma_angles)
    lower = g <= math.pi / 2 + 1e-12
    c = np.radians(p.c_angles)
    trapezoid_down = np.trapezoid(np.trapezoid(p.candela[:, lower] * np.sin(g[lower]), g[lower], axis=1), c)
    # Same tolerance reasoning as for the total flux, on the lower zone, in fractions.
    sampling = abs(trapezoid_down / p.luminous_flux - down)
    tolerance = 0.5 * 10.0**-(len(dff_text.split(".")[1]) if "." in dff_text else 0) / 100 + 2 * sampling
    assert down == pytest.approx(float(dff_text) / 100.0, abs=tolerance)


@pytest.mark.realdata
def test_real_ldt_lamp_count_is_not_a_flux_multiplier():
    # The fluorescent template has 2 lamps with a *total* flux of 8100 lm (line 26c) and
    # LORL 40.3 %: the integral (3262.7 lm) matches 0.403 × 8100 = 3264.3 lm, not × 16200.
    p = read_eulumdat(realdata("photometry/eulumdatrs_fluorescent_luminaire.ldt"))
    assert p.metadata["lamp_sets"][0]["n_lamps"] == 2
    assert p.luminous_flux == pytest.approx(0.403 * 8100, rel=0.005)


@pytest.mark.realdata
def test_real_negative_lamp_count_marks_absolute_photometry():
    p = read_eulumdat(realdata("photometry/sensor.ldt"))
    assert p.metadata["lamp_sets"][0]["n_lamps"] == -1 and p.metadata["absolute"]
    assert p.luminous_flux == pytest.approx(35.0, rel=0.005)  # line 26c = luminaire flux


@pytest.mark.realdata
def test_real_symmetry_expansions():
    quadrant = read_eulumdat(realdata("photometry/biolux_dn150.ldt"))  # Isym 4
    assert quadrant.metadata["symmetry_indicator"] == 4
    for k, angle in enumerate(quadrant.c_angles):
        for mirror in ((360.0 - angle) % 360.0, (180.0 - angle) % 360.0):
            np.testing.assert_array_equal(quadrant.candela[k], quadrant.candela[quadrant.c_angles == mirror][0])
    ies = read_ies(realdata("photometry/radiance_mgflib_examp1.ies"))  # 0–90°: quadrant
    assert ies.metadata["symmetry"] == "quadrant"
    c, g = random_directions(200)
    np.testing.assert_allclose(ies.intensity(c, g), ies.intensity(-c, g), rtol=1e-12)
    np.testing.assert_allclose(ies.intensity(c, g), ies.intensity(np.pi - c, g), rtol=1e-12)
    rotational = read_eulumdat(realdata("photometry/sensor.ldt"))  # Isym 1
    np.testing.assert_array_equal(rotational.candela[0], rotational.candela[-1])
    np.testing.assert_allclose(rotational.intensity(c, g), rotational.intensity(c + 1.0, g), rtol=1e-12)


@pytest.mark.realdata
def test_real_absolute_ies_matches_its_catalogue_flux():
    # Interlight high-bay: absolute photometry (lumens per lamp = −1) whose [LUMINAIRE]
    # keyword states "5300LM" — a catalogue figure, rounded to 100 lm (±50 lm ≈ ±0.95 %).
    p = read_ies(realdata("photometry/eulumdatrs_Indoor_60W_120G_5300LM_5000K_OVNI.ies"))
    assert p.metadata["absolute"] and p.metadata["multiplier"] == 0.4597
    assert "5300LM" in p.metadata["LUMINAIRE"]
    assert p.luminous_flux == pytest.approx(5300.0, rel=50 / 5300 + 2 * relative_sampling_error(p))
    assert (p.width, p.length) == (-0.3, -0.3)  # circular opening, 0.3 m diameter


# ------------------------------------------------------------------------------------------
# Sampling: the solver draws emission directions from the same Photometry it evaluates
# ------------------------------------------------------------------------------------------


@pytest.mark.realdata
@pytest.mark.parametrize("name", ["eulumdatrs_MAXWELL-8-T4_MEASURED_IESNA.ies", "eulumdatrs_floor_uplight.ldt"])
def test_sampled_directions_reproduce_the_zonal_fluxes(name):
    # Reference: zonal_flux, the exact integral of the bilinear distribution over γ zones
    # (checked above against analytic distributions). The weighted fraction of samples in a
    # zone, mean(w·1_zone), estimates Φ_zone/Φ without bias; its standard error is taken from
    # the samples themselves and 5 of them allowed (a false alarm once in ~3·10⁶ runs).
    p = read_photometry(realdata(f"photometry/{name}"))
    frame = np.eye(3)  # local = world: γ from +z, C from +x
    directions, weight = p.sample(np.random.default_rng(7), 200_000, frame)
    np.testing.assert_allclose(np.linalg.norm(directions, axis=1), 1.0, rtol=1e-12)
    gamma = np.arccos(np.clip(directions[:, 2], -1.0, 1.0))
    c = np.mod(np.arctan2(directions[:, 1], directions[:, 0]), 2 * math.pi)
    # every sample points where the distribution emits, and its weight is I/(Φ·p)
    assert np.all(p.intensity(c, gamma) > 0)
    edges = np.radians([0.0, 30.0, 60.0, 90.0, 120.0, 180.0])
    for lo, hi in zip(edges[:-1], edges[1:]):
        inside = weight * ((gamma >= lo) & (gamma < hi))
        exact = p.zonal_flux(lo, hi) / p.luminous_flux
        se = inside.std() / math.sqrt(inside.size)
        assert abs(inside.mean() - exact) <= 5 * se + 1e-12, (lo, hi, inside.mean(), exact, se)
    se = weight.std() / math.sqrt(weight.size)
    assert abs(weight.mean() - 1.0) <= 5 * se + 1e-12


def test_isotropic_and_function_distributions_are_photometries():
    # Analytic: an isotropic point of I cd emits 4π·I; the tabulated I0·cos⁺γ down-light emits
    # π·I0 (its bilinear interpolant on a 1° grid within 1e-4 of the analytic integral:
    # the chord error of cos over 1°, ≈ (π/180)²/12 relative).
    assert Photometry.isotropic(12.0).luminous_flux == pytest.approx(48 * math.pi, rel=EXACT)
    down = Photometry.from_function(lambda c, g: 100.0 * np.clip(np.cos(g), 0.0, None))
    assert down.format == "function" and down.luminous_flux == pytest.approx(100 * math.pi, rel=1e-4)
    with pytest.raises(BadInputError, match="intensity must be a finite positive number"):
        Photometry.isotropic(0.0)
