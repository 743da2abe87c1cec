"""False-colour PNG of a luminance map with a logarithmic legend in cd/m²."""

import numpy as np

from .._atomic import atomic_path


def false_colour_range(luminance):
    """Legend range [cd·m⁻²]: 0.5th to 99.9th percentile of finite positive values, ≥ 1 decade."""
    values = luminance[np.isfinite(luminance) & (luminance > 0)]
    if values.size == 0:
        return 1e-3, 1.0
    low, high = np.percentile(values, [0.5, 99.9])
    low = max(low, 1e-3)
    high = max(high, low * 10.0)
    return float(low), float(high)


def write_false_colour_png(lmap, path, *, luminance_range=None, title=None, colormap="turbo", dpi=100):
    """Write a false-colour PNG of ``lmap`` (atomic).

    Parameters
    ----------
    lmap : LuminanceMap
    path : path-like
    luminance_range : (float, float), optional
        Legend limits [cd·m⁻²]; default :func:`false_colour_range`.
    title : str, optional
    colormap : str
        Matplotlib colour map name.

    Unknown (NaN) pixels are grey; values outside the range take the end colours. Uncalibrated
    maps say so in the title.
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    from matplotlib import colors
    from matplotlib.figure import Figure

    luminance = np.asarray(lmap.luminance, dtype=np.float64)
    low, high = luminance_range or false_colour_range(luminance)
    rows, cols = luminance.shape
    width = 7.0
    height = max(2.5, width * rows / max(cols, 1) * 0.85 + 0.8)
    fig = Figure(figsize=(width, height), dpi=dpi)
    ax = fig.add_axes((0.03, 0.06, 0.78, 0.84))
    cmap = matplotlib.colormaps[colormap].with_extremes(bad="0.5")
    shown = np.where(np.isnan(luminance) | (luminance > 0), luminance, low)  # NaN stays grey
    image = ax.imshow(
        np.ma.masked_invalid(shown), cmap=cmap, norm=colors.LogNorm(vmin=low, vmax=high), interpolation="nearest"
    )
    ax.set_axis_off()
    cax = fig.add_axes((0.84, 0.1, 0.035, 0.76))
    bar = fig.colorbar(image, cax=cax, extend="both")
    bar.set_label("luminance [cd/m²]")
    label = title or "luminance"
    if not lmap.calibrated:
        label += " (uncalibrated)"
    ax.set_title(label, fontsize=10)
    with atomic_path(path) as temp:
        fig.savefig(temp, format="png", metadata={"Comment": (
            "false colour; luminance <= 0 (noise around zero) shown at the legend's lower end; "
            "the OpenEXR map keeps signed values")})
