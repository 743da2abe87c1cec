"""Synthetic luminance scenes with known values [cd/m²]."""

import numpy as np


def uniform_field(shape, luminance):
    """A uniform field of ``luminance`` [cd·m⁻²]."""
    return np.full(shape, float(luminance))


def interior_scene(shape, *, luminaires=((0.18, 0.3, 12000.0), (0.18, 0.7, 12000.0)), background=(20.0, 120.0),
                   patch=(0.62, 0.5, 0.1, 60.0), luminaire_radius=0.05):
    """A smooth interior-like scene: a vertical gradient (floor to ceiling), a grey target and
    bright round luminaires.

    Parameters
    ----------
    shape : (int, int)
    luminaires : sequence of (row fraction, col fraction, luminance [cd·m⁻²])
    background : (float, float)
        Luminance at the bottom and top edges [cd·m⁻²] (log-linear in between).
    patch : (row fraction, col fraction, half-size fraction, luminance)
        A uniform square target for spot readings.
    luminaire_radius : float
        Radius as a fraction of the image height.

    Returns
    -------
    ndarray, float64, ``shape``
    """
    rows, cols = shape
    rr, cc = np.meshgrid(np.arange(rows) / rows, np.arange(cols) / cols, indexing="ij")
    bottom, top = background
    scene = top * (bottom / top) ** rr * (1.0 + 0.15 * np.cos(2 * np.pi * cc))
    pr, pc, half, value = patch
    aspect = cols / rows
    scene[(abs(rr - pr) <= half) & (abs(cc - pc) * aspect <= half)] = value
    for r0, c0, value in luminaires:
        inside = (rr - r0) ** 2 + ((cc - c0) * aspect) ** 2 <= luminaire_radius**2
        scene[inside] = value
    return scene


def disk_sources_scene(directions, *, background, sources):
    """Luminance of a uniform background with uniform circular sources, per pixel direction.

    Parameters
    ----------
    directions : ndarray, shape (rows, cols, 3)
        Unit pixel directions (NaN where invalid; those pixels come out NaN).
    background : float
        Background luminance [cd·m⁻²].
    sources : sequence of (direction, angular_radius, luminance)
        Each source: its centre direction (3-vector, normalised here), its angular radius
        [rad] (a spherical cap: solid angle 2π(1 − cos radius)) and its luminance [cd·m⁻²].
        Later sources paint over earlier ones.

    Returns
    -------
    ndarray, float64, shape (rows, cols)
        The pixel's luminance is that of the region its centre direction lies in.
    """
    d = np.asarray(directions, dtype=np.float64)
    scene = np.full(d.shape[:-1], float(background))
    for centre, radius, value in sources:
        c = np.asarray(centre, dtype=np.float64)
        c = c / np.linalg.norm(c)
        with np.errstate(invalid="ignore"):
            scene[d @ c >= np.cos(radius)] = value
    scene[~np.isfinite(d[..., 0])] = np.nan
    return scene
