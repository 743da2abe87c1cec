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


def window_scene(directions, *, background, windows=(), disks=()):
    """A daylit-room-like scene: windows with luminance gradients and disk sources.

    Parameters
    ----------
    directions : ndarray, shape (rows, cols, 3)
        Unit pixel directions in the camera frame (x right, y down, z forward; NaN where
        invalid: those pixels come out NaN).
    background : (float, float)
        Background luminance [cd·m⁻²] at elevation −90° and +90° (linear in between: a
        darker floor, a brighter ceiling).
    windows : sequence of dict
        Each a spherical rectangle in azimuth a = atan2(x, z) and elevation
        e = atan2(−y, √(x² + z²)) [deg]: ``azimuth`` (a0, a1), ``elevation`` (e0, e1) and
        ``luminance`` (L at e0, L at e1) [cd·m⁻²], log-linear in elevation (a sky brighter
        upwards), optionally ``side_gradient`` g: a factor 1 + g·(a − a_mid)/(a1 − a0)
        (sun-side brighter), and ``mullions``: azimuths [deg] of vertical bars of width
        ``mullion_width`` [deg] (default 2°) at the background luminance. Its solid angle
        is (a1 − a0)·(sin e1 − sin e0) [sr] (angles in radians) less the mullions.
    disks : sequence of (direction, angular_radius, luminance)
        Uniform circular sources as in :func:`disk_sources_scene`, painted last.

    Returns
    -------
    ndarray, float64, shape (rows, cols)
    """
    d = np.asarray(directions, dtype=np.float64)
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    with np.errstate(invalid="ignore"):
        azimuth = np.degrees(np.arctan2(x, z))
        elevation = np.degrees(np.arctan2(-y, np.hypot(x, z)))
        low, high = background
        scene = low + (high - low) * (elevation + 90.0) / 180.0
        for w in windows:
            a0, a1 = w["azimuth"]
            e0, e1 = w["elevation"]
            l0, l1 = w["luminance"]
            inside = (azimuth >= a0) & (azimuth <= a1) & (elevation >= e0) & (elevation <= e1)
            t = (elevation - e0) / (e1 - e0)
            value = l0 * (l1 / l0) ** t * (1.0 + w.get("side_gradient", 0.0)
                                          * (azimuth - (a0 + a1) / 2) / (a1 - a0))
            for m in w.get("mullions", ()):
                inside &= np.abs(azimuth - m) > w.get("mullion_width", 2.0) / 2
            scene = np.where(inside, value, scene)
    if disks:
        lit = disk_sources_scene(d, background=-1.0, sources=disks)
        scene = np.where(lit >= 0, lit, scene)
    scene[~np.isfinite(d[..., 0])] = np.nan
    return scene
