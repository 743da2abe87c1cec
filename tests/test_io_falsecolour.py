"""False-colour PNG: a valid image of the expected size, colours from the colour map.

References: the PNG signature (ISO/IEC 15948), Pillow's decoder, matplotlib's own ``turbo``
colour map for the end colours, and the documented grey (0.5) for unknown pixels.
"""

import matplotlib
import numpy as np
import pytest
from PIL import Image

from lsadphoto.io.falsecolour import write_false_colour_png
from lsadphoto.luminance_map import LuminanceMap

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
#: 8-bit PNG: a colour is stored to ±½ of 1/255; 1.5/255 allows for a neighbouring
#: pixel's antialiasing never reaching the centre of a large uniform image.
COLOUR_ATOL = 1.5 / 255


def _write(tmp_path, luminance, **kwargs):
    path = tmp_path / "fc.png"
    write_false_colour_png(LuminanceMap(luminance), path, **kwargs)
    assert path.read_bytes()[:8] == PNG_SIGNATURE
    with Image.open(path) as image:
        image.load()
        assert image.format == "PNG"
        return np.asarray(image.convert("RGB"), dtype=np.float64) / 255.0


def _expected_size(rows, cols):
    """Figure size of the writer: 7 in wide at 100 dpi; height from the aspect, ≥ 2.5 in.
    (Matplotlib truncates a fractional pixel count; compared to ±1 px.)"""
    height = max(2.5, 7.0 * rows / max(cols, 1) * 0.85 + 0.8)
    return 100 * height, 700


def _image_centre(pixels):
    """Colour at the centre of the image axes (fraction 0.03…0.81 × 0.06…0.90 of the figure)."""
    rows, cols, _ = pixels.shape
    x = int((0.03 + 0.78 / 2) * cols)
    y = int((1.0 - (0.06 + 0.84 / 2)) * rows)  # figure fractions count from the bottom
    return pixels[y, x]


@pytest.mark.parametrize(
    "shape", [(1, 1), (40, 60), (300, 20), (20, 300)], ids=["1x1", "landscape", "tall", "wide"]
)
def test_png_size(tmp_path, shape):
    rng = np.random.default_rng(0)
    pixels = _write(tmp_path, rng.uniform(1, 1000, shape))
    height, width = _expected_size(*shape)
    assert pixels.shape[1] == width and abs(pixels.shape[0] - height) <= 1


def test_all_nan_is_grey(tmp_path):
    pixels = _write(tmp_path, np.full((30, 40), np.nan))
    np.testing.assert_allclose(_image_centre(pixels), [0.5, 0.5, 0.5], atol=COLOUR_ATOL)


def test_constant_and_zero_maps(tmp_path):
    turbo = matplotlib.colormaps["turbo"]
    # A constant map: default range [c, 10c], so it shows the lowest colour.
    pixels = _write(tmp_path, np.full((30, 40), 250.0))
    np.testing.assert_allclose(_image_centre(pixels), turbo(0.0)[:3], atol=COLOUR_ATOL)
    # Zero (not positive): shown at the bottom of the scale, not as unknown.
    pixels = _write(tmp_path, np.zeros((30, 40)))
    np.testing.assert_allclose(_image_centre(pixels), turbo(0.0)[:3], atol=COLOUR_ATOL)


@pytest.mark.parametrize("value, fraction", [(1.0, 0.0), (1e4, 1.0), (1e2, 0.5), (1e6, 1.0), (1e-3, 0.0)])
def test_explicit_range_colours(tmp_path, value, fraction):
    """Logarithmic scale over [1, 1e4]: 100 cd/m² is halfway; values outside clip to the ends."""
    turbo = matplotlib.colormaps["turbo"]
    pixels = _write(tmp_path, np.full((30, 40), value), luminance_range=(1.0, 1e4), title="desk")
    np.testing.assert_allclose(_image_centre(pixels), turbo(fraction)[:3], atol=COLOUR_ATOL)


def test_one_pixel_map(tmp_path):
    pixels = _write(tmp_path, np.array([[42.0]]), title="single pixel")
    height, width = _expected_size(1, 1)
    assert pixels.shape[1] == width and abs(pixels.shape[0] - height) <= 1
    np.testing.assert_allclose(_image_centre(pixels), matplotlib.colormaps["turbo"](0.0)[:3], atol=COLOUR_ATOL)


def test_writes_into_new_directory_without_leftovers(tmp_path):
    target = tmp_path / "figures" / "map.png"
    write_false_colour_png(LuminanceMap(np.ones((4, 4))), target)
    assert [p.name for p in target.parent.iterdir()] == ["map.png"]
