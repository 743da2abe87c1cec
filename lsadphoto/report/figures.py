"""Figures of scored maps: the glare-source map (the paper's Figure 3) and the contrast map.

Both are written atomically as PNG with matplotlib's Agg backend (no screen needed).
"""

import numpy as np

from .._atomic import atomic_path
from ..io.falsecolour import false_colour_range

__all__ = ["write_glare_source_png", "write_contrast_png", "write_ratio_png"]


def _figure(shape, width=7.0, dpi=100):
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib.figure import Figure

    rows, cols = shape
    height = max(2.5, width * rows / max(cols, 1) * 0.85 + 0.8)
    return Figure(figsize=(width, height), dpi=dpi)


def write_glare_source_png(luminance, labels, path, *, title=None, dpi=100):
    """Glare-source pixels in colour over the luminance image in grey (log scale).

    Parameters
    ----------
    luminance : ndarray, shape (rows, cols)
        Luminance [cd·m⁻²] (NaN unknown, shown black).
    labels : ndarray of int, shape (rows, cols)
        Source number + 1 per pixel, 0 elsewhere (from the grouping).
    path : path-like
        PNG to write.
    """
    import matplotlib
    from matplotlib import colors

    luminance = np.asarray(luminance, dtype=np.float64)
    # Grey scale from the non-source pixels, so that the scene around the sources shows.
    low, high = false_colour_range(np.where(labels > 0, np.nan, luminance))
    with np.errstate(invalid="ignore", divide="ignore"):
        grey = np.clip((np.log10(np.maximum(luminance, low)) - np.log10(low))
                       / (np.log10(high) - np.log10(low)), 0.0, 1.0)
    grey = np.where(np.isfinite(grey), grey, 0.0)
    rgb = 0.1 + 0.75 * np.repeat(grey[..., None], 3, axis=-1)
    n = int(labels.max()) if labels.size else 0
    if n:
        palette = matplotlib.colormaps["tab10"](np.arange(n) % 10)[:, :3]
        mask = labels > 0
        rgb[mask] = 0.35 * rgb[mask] + 0.65 * palette[labels[mask] - 1]
    fig = _figure(luminance.shape, dpi=dpi)
    ax = fig.add_axes((0.03, 0.06, 0.94, 0.84))
    ax.imshow(rgb, interpolation="nearest", norm=colors.NoNorm())
    ax.set_axis_off()
    ax.set_title(title or f"glare sources: {n} (colours) over luminance (grey, log)", fontsize=10)
    with atomic_path(path) as temp:
        fig.savefig(temp, format="png")


def write_contrast_png(contrast, path, *, title=None, dpi=100):
    """The Q criterion's per-pixel contrast map K [rad⁻¹] on a log scale (0 and NaN grey)."""
    import matplotlib
    from matplotlib import colors

    contrast = np.asarray(contrast, dtype=np.float64)
    positive = contrast[np.isfinite(contrast) & (contrast > 0)]
    fig = _figure(contrast.shape, dpi=dpi)
    ax = fig.add_axes((0.03, 0.06, 0.78, 0.84))
    cmap = matplotlib.colormaps["magma"].with_extremes(bad="0.5")
    shown = np.ma.masked_where(~(np.isfinite(contrast) & (contrast > 0)), contrast)
    if positive.size:
        low, high = np.percentile(positive, [1.0, 99.9])
        norm = colors.LogNorm(vmin=low, vmax=max(high, low * 10))
    else:
        norm = colors.LogNorm(vmin=1.0, vmax=10.0)
    image = ax.imshow(shown, cmap=cmap, norm=norm, interpolation="nearest")
    ax.set_axis_off()
    cax = fig.add_axes((0.84, 0.1, 0.035, 0.76))
    fig.colorbar(image, cax=cax).set_label("generalised contrast K [1/rad]")
    ax.set_title(title or "Q criterion: contrasts above the cut-off", fontsize=10)
    with atomic_path(path) as temp:
        fig.savefig(temp, format="png")


def write_ratio_png(ratio, path, *, title=None, limit=2.0, dpi=100):
    """Per-pixel ratio model/photo on a diverging log scale from 1/limit to limit (NaN grey)."""
    import matplotlib
    from matplotlib import colors

    ratio = np.asarray(ratio, dtype=np.float64)
    fig = _figure(ratio.shape, dpi=dpi)
    ax = fig.add_axes((0.03, 0.06, 0.78, 0.84))
    cmap = matplotlib.colormaps["RdBu_r"].with_extremes(bad="0.5")
    shown = np.ma.masked_where(~(np.isfinite(ratio) & (ratio > 0)), ratio)
    image = ax.imshow(shown, cmap=cmap, norm=colors.LogNorm(vmin=1.0 / limit, vmax=limit),
                      interpolation="nearest")
    ax.set_axis_off()
    cax = fig.add_axes((0.84, 0.1, 0.035, 0.76))
    fig.colorbar(image, cax=cax, extend="both").set_label("model / photo")
    ax.set_title(title or "luminance ratio model / photo", fontsize=10)
    with atomic_path(path) as temp:
        fig.savefig(temp, format="png")
