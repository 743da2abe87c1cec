"""Per-pixel geometry cache: the cached maps against the projections' own (uncached)
methods, the observer frame and the position index, plus cache and read-only behaviour."""

import math

import numpy as np
import pytest

from lsadphoto.errors import BadInputError
from lsadphoto.geometry import (
    IdealFisheyeProjection,
    ObserverFrame,
    OpenCVFisheyeProjection,
    OpenCVPinholeProjection,
    PinholeProjection,
    clear_geometry_cache,
    pixel_geometry,
    position_index,
    visual_field,
)
from lsadphoto.geometry import field as field_module
from lsadphoto.geometry._spherical import quad_solid_angle

KINDS = ["equidistant", "equisolid", "orthographic", "stereographic"]

OTHER_MODELS = {
    "pinhole": PinholeProjection(150.0, 160.0, 99.3, 70.8, 203, 149),
    "opencv-pinhole": OpenCVPinholeProjection(150.0, 150.0, 101.2, 74.9, (-0.2, 0.05, 0.001, -0.002, 0.0), 203, 149),
    "opencv-fisheye": OpenCVFisheyeProjection(60.0, 60.0, 101.7, 73.2, (0.05, -0.01, 0.003, -0.0005), 203, 149),
    # Image corners beyond the fold of the mapping (θ_max = 131.6°): NaN there, no warnings.
    "opencv-fisheye-folded": OpenCVFisheyeProjection(45.0, 46.0, 101.7, 73.2, (0.05, -0.01, 0.003, -0.0005),
                                                     203, 149),
}


@pytest.fixture(autouse=True)
def _fresh_cache():
    clear_geometry_cache()
    yield
    clear_geometry_cache()


def _fisheye(kind):
    return IdealFisheyeProjection(kind, 101.3, 72.6, 70.0, 180.0, 203, 149)


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize("circle", ["inside", "cut"])
def test_ideal_fisheye_maps_equal_the_projection_methods_exactly(kind, circle):
    # "cut": an off-centre circle that the image edges cut on three sides, so that the spans
    # of the kernel (the chord of the circle per row, plus a margin) are clipped to the image.
    if circle == "inside":
        cam = _fisheye(kind)
    else:
        cam = IdealFisheyeProjection(kind, 60.2, 80.7, 95.0, 180.0, 203, 149)
    geometry = pixel_geometry(cam)
    rows, cols = cam.pixel_grid()
    # Same elementwise arithmetic on the same inputs (corner offsets (c ± ½) − cx are exact
    # in both paths and both use quad_solid_angle_components). The compiled kernel takes the
    # equidistant tan(θ/2) from its branch-free Cephes tan (within 2 ulp of the C library's),
    # numpy from its own tan (SIMD versions where the CPU has them: AVX-512 measured 1 ulp
    # from libm), so the equidistant maps agree to a few ulp and the others bit for
    # bit: directions (unit vectors) within 4 eps, solid angles, differences of corner
    # terms, within 128 eps relative (measured at most 53).
    eps = np.finfo(np.float64).eps
    directions = cam.directions(rows, cols)
    assert np.array_equal(np.isnan(geometry.directions), np.isnan(directions))
    np.testing.assert_allclose(geometry.directions, directions, rtol=0, atol=4 * eps)
    np.testing.assert_allclose(geometry.solid_angle, cam.solid_angles(rows, cols), rtol=128 * eps, atol=0)
    if kind != "equidistant":
        np.testing.assert_array_equal(geometry.directions, directions)
    np.testing.assert_array_equal(geometry.valid, cam.valid(rows, cols))
    assert geometry.directions.dtype == geometry.solid_angle.dtype == np.float64
    assert geometry.directions.shape == (149, 203, 3) and geometry.valid.dtype == bool


@pytest.mark.parametrize("name", OTHER_MODELS)
def test_other_models_match_the_projection_methods(name):
    cam = OTHER_MODELS[name]
    geometry = pixel_geometry(cam)
    rows, cols = cam.pixel_grid()
    ok = geometry.valid
    assert ok.sum() > 0.5 * ok.size
    reference = cam.directions(rows, cols)
    assert np.all(np.isnan(geometry.directions[~ok])) and np.all(geometry.solid_angle[~ok] == 0)
    if name.startswith("opencv-fisheye"):
        # pixel_geometry inverts θd(θ) = ρ by table + Newton to rounding; the model's own
        # solver stops at a residual below 1e-12, i.e. θ within 1e-12/(dθd/dθ) (dθd/dθ ≥ 0.3
        # on this image): 1e-11 bounds the difference (measured 8e-13).
        np.testing.assert_allclose(geometry.directions[ok], reference[ok], rtol=0, atol=1e-11)
        # Corner directions differ by that much over pixel edges of 1.7e-2 rad: relative
        # 1e-9 on the solid angle (measured 6e-11).
        rtol = 1e-9
    else:
        # Directions come from the model's own directions(): equal bit for bit.
        np.testing.assert_array_equal(geometry.directions[ok], reference[ok])
        # Solid angles: the same geodesic quad (for the pinhole the exact rectangle formula,
        # the same spherical quadrilateral since straight image edges map to great circles),
        # evaluated with different algebra: relative 1e-11 (measured ≤ 1e-13).
        rtol = 1e-11
    np.testing.assert_allclose(geometry.solid_angle[ok], cam.solid_angles(rows, cols)[ok], rtol=rtol)


@pytest.mark.parametrize("cx", [20.0, 20.5, 19.75, 20.3])
def test_equidistant_directions_within_ulps_of_libm_tan(cx):
    # The kernel takes tan(θ/2) from the branch-free Cephes tan (tan_half_range, within 2 ulp
    # of math.tan, tested below), so that its rows run on SIMD lanes. Reference: the model's
    # operations written out per pixel in Python with math.tan (the C library's). A tan 2 ulp
    # off moves s = 2t/(1 + t²) and c = (1 − t²)/(1 + t²) by at most 2 ulp of t times
    # |ds/dt|·t, |dc/dt|·t ≤ 1, plus their own roundings: unit-vector components within
    # 4 eps (measured at most 1.5 eps).
    eps = np.finfo(np.float64).eps
    cam = IdealFisheyeProjection("equidistant", cx, 18.5, 20.0, 180.0, 41, 38)
    _, p, _ = field_module._fisheye_kernel_parameters(cam)
    coefficient = p[3]
    geometry = pixel_geometry(cam)
    checked = 0
    for r in range(38):
        y = r - 18.5
        for c in range(41):
            if not geometry.valid[r, c]:
                continue
            x = c - cx
            radius = math.sqrt(x * x + y * y)
            t = math.tan(min(radius * coefficient, math.pi) * 0.5)
            t2 = t * t
            q = 2.0 * t / (1.0 + t2) / radius if radius > 0 else 0.0
            np.testing.assert_allclose(geometry.directions[r, c],
                                       (q * x, q * y, (1.0 - t2) / (1.0 + t2)), rtol=0,
                                       atol=4 * eps)
            checked += 1
    assert checked > 1000


def test_solid_angle_kernel_against_analytic_squares():
    # Reference: a square of half-size a on the tangent plane at a unit vector c (corners
    # c + a(±e1 ± e2)) subtends 4·arctan(a²/√(1 + 2a²)) (the rectangle formula of FORMULAS.md
    # §2.4.2 for a centred square), for random orientations and a from 1e-5 to 0.5 (pixels of
    # 24-MP images are ~5e-4 wide).
    from lsadphoto.geometry.field import quad_solid_angle_components

    rng = np.random.default_rng(3)
    centre = rng.normal(size=(2000, 3))
    centre /= np.linalg.norm(centre, axis=1)[:, None]
    half = 10 ** rng.uniform(-5, -0.3, 2000)
    e1 = np.cross(centre, [0.3, 0.5, 0.8])
    e1 /= np.linalg.norm(e1, axis=1)[:, None]
    e2 = np.cross(centre, e1)
    corners = [centre + half[:, None] * (sx * e1 + sy * e2) for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1))]
    corners = [c / np.linalg.norm(c, axis=1)[:, None] for c in corners]
    ours = quad_solid_angle_components(*[tuple(c.T) for c in corners])
    exact = 4 * np.arctan(half * half / np.sqrt(1 + 2 * half * half))
    # The unit corner vectors are stored to ~eps absolute, so a quad of edge 2a is known to
    # relative ~eps/a (2e-11 at a = 1e-5; measured max 6e-12). 1e-15/a + 1e-13 bounds it.
    assert np.all(np.abs(ours - exact) <= (1e-15 / half + 1e-13) * exact)
    # For quads of 1e-4 sr and up, the per-triangle arctan2 form of _spherical agrees too.
    big = exact > 1e-4
    np.testing.assert_allclose(ours[big], quad_solid_angle(*[c[big] for c in corners]), rtol=1e-11)
    # Octant: exactly π/2 (Girard: three right angles).
    x, y, z = np.eye(3)
    assert quad_solid_angle_components(tuple(x), tuple(y), tuple(z), tuple(z)) == pytest.approx(math.pi / 2, rel=1e-15)
    # A hemisphere-sized quad (each triangle π: the arctan2 branch with a negative half-angle
    # sum wrapped by 2π): corners on the equator at 45°, 135°, 225°, 315°, lifted by 1e-9
    # towards +z, bound the upper hemisphere, 2π up to the 1e-9 lift.
    eq = [np.array([math.cos(a), math.sin(a), 0.0]) for a in np.radians([45.0, 135.0, 225.0, 315.0])]
    tilt = [tuple(_unit(v + np.array([0, 0, 1e-9]))) for v in eq]
    assert quad_solid_angle_components(*tilt) == pytest.approx(2 * math.pi, rel=1e-6)


def _unit(v):
    return v / np.linalg.norm(v)


def test_total_solid_angle_of_the_hemisphere():
    cam = IdealFisheyeProjection("equisolid", 199.5, 199.5, 200.0, 180.0, 400, 400)
    geometry = pixel_geometry(cam)
    # Reference 2π for the 180° circle; the centre rule misses it by the rim band only
    # (measured 7.5e-5 relative at R = 500 px, test_geometry_fisheye); 5e-4 at R = 200 px.
    assert geometry.solid_angle.sum() == pytest.approx(2 * math.pi, rel=5e-4)


def test_cache_identity_keys_and_read_only():
    cam = _fisheye("equidistant")
    first = pixel_geometry(cam)
    assert pixel_geometry(cam) is first
    # An equal model built anew hits the same entry (key: the model's to_dict()).
    assert pixel_geometry(IdealFisheyeProjection.from_dict(cam.to_dict())) is first
    other = pixel_geometry(cam.binned(2))
    assert other is not first and other.valid.shape == (74, 101)
    for array in (first.directions, first.solid_angle, first.valid):
        assert not array.flags.writeable
        with pytest.raises(ValueError):
            array[0, 0] = 0
    # LRU of CACHE_SIZE entries: filling it with other sizes evicts the first.
    for k in range(field_module.CACHE_SIZE):
        pixel_geometry(IdealFisheyeProjection("equidistant", 10.0, 10.0, 10.0, 180.0, 21 + k, 21))
    assert pixel_geometry(cam) is not first
    with pytest.raises(BadInputError, match="Projection"):
        pixel_geometry("fisheye")


@pytest.mark.parametrize("name", ["opencv-fisheye", "opencv-pinhole"])
def test_blocks_and_threads_do_not_change_the_result(monkeypatch, name):
    # The compiled fisheye kernel (corner rows carried from block to block) and the numpy
    # path of the other models, in 3-row blocks and on one thread against the defaults.
    import numba

    cam = OTHER_MODELS[name]
    whole = pixel_geometry(cam)
    clear_geometry_cache()
    monkeypatch.setattr(field_module, "_BLOCK_PIXELS", 3 * 203 + 5)  # 3-row blocks, 50 of them
    monkeypatch.setattr(field_module, "_KERNEL_BLOCK_PIXELS", 3 * 203 + 5)
    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        split = pixel_geometry(cam)
    finally:
        numba.set_num_threads(threads)
    np.testing.assert_array_equal(split.directions, whole.directions)
    np.testing.assert_array_equal(split.solid_angle, whole.solid_angle)
    np.testing.assert_array_equal(split.valid, whole.valid)


def test_branch_free_atan2_against_libm():
    # The visual-field kernel's atan2 (Cephes' atan, for y ≥ 0) against math.atan2 on
    # ratios from 1e-12 to 1e12 in all four quadrant reflections: within 2 ulp of the result
    # (Moshier's peak error 2.2e-16 relative, plus the reflection's rounding). Far below the
    # 1e-14 rad to which σ and τ are tested.
    # the kernels' own decorator: it loads numba and hands their intrinsics to the kernels
    from lsadphoto._compiled import njit
    from lsadphoto.geometry._kernels import atan2_nonnegative

    @njit()
    def many(y, x, out):
        for i in range(y.size):
            out[i] = atan2_nonnegative(y[i], x[i])

    rng = np.random.default_rng(5)
    y = 10 ** rng.uniform(-6, 6, 200_000)
    x = 10 ** rng.uniform(-6, 6, 200_000) * rng.choice([-1.0, 1.0], 200_000)
    y[:4], x[:4] = [0.0, 0.0, 1.0, 1.0], [1.0, -1.0, 0.0, 1.0]  # 0, π, π/2, π/4
    out = np.empty_like(y)
    many(y, x, out)
    exact = np.array([math.atan2(a, b) for a, b in zip(y, x)])
    assert np.all(np.abs(out - exact) <= 2 * np.spacing(exact))
    assert out[0] == 0.0 and out[1] == math.pi and out[2] == math.pi / 2
    nan = np.array([np.nan, 1.0, 0.0]), np.array([1.0, np.nan, 0.0])
    many(*nan, out[:3])
    assert np.isnan(out[:2]).all() and out[2] == 0.0  # NaN propagates; atan2(0, 0) = 0


FRAMES = {  # rolled: rows crossing the line of sight's horizon; along the axis: none do
    "rolled": ObserverFrame.levelled(roll_deg=4.0, pitch_deg=-8.0),
    "axis": ObserverFrame(),
}


def _assert_float32_of(stored, reference, *, rtol=0.0, atol=0.0):
    """``stored`` (float32) is a float64 value within ``rtol``·|reference| + ``atol`` of
    ``reference`` rounded once to float32: within half a float32 ulp of that value."""
    assert stored.dtype == np.float32
    reference = np.asarray(reference, dtype=np.float64)
    half_ulp = 0.5 * np.spacing(np.abs(reference).astype(np.float32)).astype(np.float64)
    error = np.abs(stored.astype(np.float64) - reference)
    assert np.all(error <= half_ulp * (1 + 1e-9) + rtol * np.abs(reference) + atol)


@pytest.mark.parametrize("method", ["evalglare", "Guth", "Kim2011"])
@pytest.mark.parametrize("frame_name", FRAMES)
def test_visual_field_against_observer_and_position_index(method, frame_name):
    # The kernel computes the formulas a row needs (Guth's above the line of sight, Iwata's
    # below it, both in rows that cross it): each frame's rows against the references.
    cam = IdealFisheyeProjection("equidistant", 101.3, 72.6, 70.0, 200.0, 203, 149)  # reaches σ = 100°
    frame = FRAMES[frame_name]
    field = visual_field(cam, frame, position_index_method=method)
    geometry = pixel_geometry(cam)
    ok = geometry.valid
    sigma, tau = frame.angles(geometry.directions)
    # Same formulas (hypot vs √(a² + b²) for the lateral part): rounding only, 1e-14 rad.
    np.testing.assert_allclose(field.sigma[ok], sigma[ok], atol=1e-14)
    np.testing.assert_allclose(field.tau[ok], tau[ok], atol=1e-13)
    # Position index from components (Iwata's β by one atan2) vs from σ, τ: rounding in β
    # (≈1e-15 rad) times dlnP/dβ (< 0.1 per degree) — 1e-12 relative is ample; the map stores
    # that float64 value rounded once to float32 (VisualField): within half a float32 ulp of
    # it, so within half an ulp of the reference plus 1e-12 relative.
    reference = position_index(sigma[ok], tau[ok], method=method)
    _assert_float32_of(field.position_index[ok], reference, rtol=1e-12)
    v = frame.axes()[0]
    _assert_float32_of(field.cos_sigma[ok], geometry.directions[ok] @ v, atol=1e-15)
    assert np.all(np.isnan(field.sigma[~ok])) and np.all(np.isnan(field.position_index[~ok]))
    assert np.all(field.cos_sigma[~ok] == 0)
    assert (field.cos_sigma[ok] < 0).any()  # the 200° circle reaches behind the observer
    assert visual_field(cam, frame, position_index_method=method) is field
    other = FRAMES["axis" if frame_name == "rolled" else "rolled"]
    assert visual_field(cam, other, position_index_method=method) is not field
    assert not field.position_index.flags.writeable


def test_visual_field_bad_input():
    cam = _fisheye("equidistant")
    with pytest.raises(BadInputError, match="position index method"):
        visual_field(cam, ObserverFrame(), position_index_method="CIE117")
    with pytest.raises(BadInputError, match="ObserverFrame"):
        visual_field(cam, (0, 0, 1))


def test_branch_free_exp_against_libm():
    # The visual-field kernel's exp (Cephes, 2ⁿ built from its bits) against math.exp: within
    # 2 ulp (measured 2) on Guth's inner argument −2τ/9 (τ ≤ 180°), on the outer exponents of
    # the position index (|x| < 25) and over the whole clamped range; NaN stays NaN, beyond
    # the range the value at the bound (position indices above the cap stay above it).
    # the kernels' own decorator: it loads numba and hands their intrinsics to the kernels
    from lsadphoto._compiled import njit
    from lsadphoto.geometry._kernels import exp_bounded

    @njit()
    def many(x, out):
        for i in range(x.size):
            out[i] = exp_bounded(x[i])

    rng = np.random.default_rng(11)
    x = np.concatenate([rng.uniform(-40.0, 0.0, 100_000), rng.uniform(-25.0, 25.0, 100_000),
                        rng.uniform(-708.0, 709.0, 100_000), [0.0, -0.0, 1e-300, 1.0, -708.0, 709.0]])
    out = np.empty_like(x)
    many(x, out)
    exact = np.array([math.exp(v) for v in x])
    assert np.all(np.abs(out - exact) <= 2 * np.spacing(exact))
    assert out[-6] == out[-5] == out[-4] == 1.0
    many(np.array([np.nan, 800.0, np.inf, 709.0, -800.0, -np.inf, -708.0]), out[:7])
    assert np.isnan(out[0]) and out[1] == out[2] == out[3] and out[4] == out[5] == out[6]


def test_branch_free_tan_against_libm():
    # The OpenCV-fisheye kernel's tan (Cephes, for 0 ≤ x ≤ π/2, where it takes tan(θ/2))
    # against math.tan: within 2 ulp (measured 2), i.e. directions within ~1e-16 of the
    # libm path; the maps are tested against the model to 1e-11.
    # the kernels' own decorator: it loads numba and hands their intrinsics to the kernels
    from lsadphoto._compiled import njit
    from lsadphoto.geometry._kernels import tan_half_range

    @njit()
    def many(x, out):
        for i in range(x.size):
            out[i] = tan_half_range(x[i])

    x = np.random.default_rng(7).uniform(0.0, math.pi / 2, 100_000)
    x[:3] = [0.0, 1e-300, math.pi / 2]
    out = np.empty_like(x)
    many(x, out)
    exact = np.array([math.tan(v) for v in x])
    assert np.all(np.abs(out - exact) <= 2 * np.spacing(np.abs(exact)))
    many(np.array([np.nan]), out[:1])
    assert np.isnan(out[0])


@pytest.mark.parametrize("one_pass", [False, True])
@pytest.mark.parametrize("method", ["evalglare", "Guth", "Kim2011"])
def test_mirrored_rows_equal_their_direct_computation(monkeypatch, one_pass, method):
    """A centred fisheye seen along its axis: each row's visual field is computed for its
    first half and copied to the mirrored pixels (_kernels._mirrored). The copied half must
    equal the same kernel run on the right part of the picture alone (spans that are not
    mirror images, so computed pixel by pixel), bit for bit."""
    from lsadphoto.geometry import _kernels

    cam = IdealFisheyeProjection("equidistant", 100.0, 72.5, 72.0, 185.0, 201, 146)
    if one_pass:  # the geometry pass computes the field from its own centre directions
        monkeypatch.setattr(field_module, "DIRECTION_MAP_MAX_PIXELS", 0)
    frame = ObserverFrame()
    field = visual_field(cam, frame, position_index_method=method)
    directions = pixel_geometry(cam).directions
    valid = pixel_geometry(cam).valid
    assert np.array_equal(field.cos_sigma, field.cos_sigma[:, ::-1])
    c = 93  # right part: columns 93…200 (the centre column 100 inside, spans not mirrored)
    part = [np.ascontiguousarray(a[:, c:]) for a in (directions, valid)]
    maps = [np.empty(part[1].shape, dtype) for dtype in (np.float64, np.float64, np.float32,
                                                         np.float32)]  # σ, τ; P, cos σ
    _kernels.visual_field_maps(part[0], part[1], -1, np.empty(0), np.empty(0),
                               *field_module._field_constants(frame.axes(), method), True, True,
                               *maps)
    for got, expected in zip((field.sigma, field.tau, field.position_index, field.cos_sigma), maps,
                             strict=True):
        assert np.array_equal(got[:, c:].view(np.uint64), expected.view(np.uint64))


MIRRORED_CAMERAS = {  # 2·cy a whole number: rows computed with their mirror images
    "centred, odd rows": IdealFisheyeProjection("equidistant", 100.0, 74.0, 72.0, 185.0, 201, 149),
    "centred, even rows": IdealFisheyeProjection("equisolid", 100.5, 74.5, 76.0, 180.0, 202, 150),
    # cy above the middle: the rows below 2·cy are computed on their own.
    "high centre": IdealFisheyeProjection("orthographic", 100.3, 50.5, 60.0, 180.0, 203, 149),
    # cy below the middle: mirror images below the picture are not written.
    "low centre": IdealFisheyeProjection("stereographic", 90.0, 110.0, 70.0, 200.0, 181, 149),
    "opencv": OpenCVFisheyeProjection(60.0, 60.0, 101.7, 74.0, (0.05, -0.01, 0.003, -0.0005),
                                      203, 149),
    # 2·cx a whole number too: columns right of cx copied from their mirror images.
    "opencv, centred columns": OpenCVFisheyeProjection(
        60.0, 61.0, 101.0, 74.0, (0.05, -0.01, 0.003, -0.0005), 203, 149),
    # cx left of the middle, the circle cut by the left edge: the columns right of the mirror
    # image of column 0 are computed on their own.
    "left centre": IdealFisheyeProjection("equidistant", 60.5, 74.0, 72.0, 185.0, 201, 149),
    "opencv, right centre": OpenCVFisheyeProjection(
        55.0, 55.0, 140.0, 74.5, (0.02, -0.004, 0.001, -0.0002), 203, 150),
}
#: Cameras of MIRRORED_CAMERAS whose columns mirror (2·cx a whole number).
MIRRORED_COLUMNS = {"centred, odd rows", "centred, even rows", "low centre",
                    "opencv, centred columns", "left centre", "opencv, right centre"}


@pytest.mark.parametrize("name", MIRRORED_CAMERAS)
@pytest.mark.parametrize("field", [False, True])
def test_mirrored_rows_equal_rows_computed_one_by_one(monkeypatch, name, field):
    """Where 2·cy is a whole number, the geometry pass computes each row above the centre
    with its mirror image below (the directions with y negated); where 2·cx is, the columns
    right of the centre from their mirror images (x negated). Reference: the same kernel
    with neither mirror, every row and column computed from its own coordinates; equal bit
    for bit, maps with and without the stored directions, with and without the visual
    field."""
    from lsadphoto.geometry import _kernels

    cam = MIRRORED_CAMERAS[name]
    rows, cols = cam.shape
    assert field_module._mirror_rows(cam.cy, rows)[0] == round(2 * cam.cy)
    assert (field_module._mirror_cols(cam.cx) >= 0) == (name in MIRRORED_COLUMNS)
    frame = ObserverFrame((0.1, -0.2, 0.97), (0.0, -1.0, 0.0))
    if field:  # one pass: geometry and visual field (no stored direction map)
        monkeypatch.setattr(field_module, "DIRECTION_MAP_MAX_PIXELS", 0)
        got, (position, cos_sigma) = field_module._compute_pixel_geometry(
            cam, (frame.axes(), "evalglare"))
    else:
        got = pixel_geometry(cam)
    model, p, table = field_module._fisheye_kernel_parameters(cam)
    maps = [np.empty((rows, cols, 3) if not field else (1, 1, 3)), np.empty((rows, cols)),
            np.empty((rows, cols), dtype=bool)]
    field_maps = [np.empty((rows, cols) if field else (1, 1), np.float32) for _ in range(2)]
    constants = field_module._field_constants(frame.axes(), "evalglare") if field else \
        (np.zeros(3), np.zeros(3), np.zeros(3), 0, 0.0)
    _kernels.fisheye_geometry(model, p, table, 7, 0, rows, -1, -1, not field, *maps, field,
                              *constants, *field_maps)
    pairs = [(got.solid_angle, maps[1]), (got.valid, maps[2])]
    if field:
        pairs += [(position, field_maps[0]), (cos_sigma, field_maps[1])]
    else:
        pairs.append((got.directions, maps[0]))
    for value, expected in pairs:
        assert value.view(np.uint8).tobytes() == expected.view(np.uint8).tobytes()
    assert got.valid.sum() > 0.3 * rows * cols
