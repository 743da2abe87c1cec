"""Luminous overflow: pixels saturated in every frame (the sun, bare LEDs), reported and repaired.

A pixel that saturates even in the shortest exposure has an unknown luminance, but a known
lower bound: the luminance at which that frame saturates. The overflow is reported (how many
pixels, their solid angle, where, the lower bound, and the share of the map's illuminance at
the lens that rests on it) instead of silently leaving NaN. Two repairs:

* **from a measured illuminance** (evalglare ``-N``): the deficit between the meter's reading
  and the map's illuminance without the overflow, spread uniformly over the overflow region:
  L = (E_meter − E_map) / Σ ω·cos θ. A deficit below the lower bound's contribution is a
  contradiction (reported, no repair).
* **from an ND-filter frame**: a frame taken through a neutral-density filter of known
  density (``nd_filter`` stops per frame in :func:`lsadphoto.luminance.luminance_from_raw`)
  joins the bracket with its exposure divided by 2^stops, so the source no longer saturates.

References
----------
J. Wienold, *evalglare* 3.0 manual (``-N``: correction of the peak from a measured E_v).
Jakubiec, Van Den Wymelenberg, Inanici & Mahic, "Accurate measurement of daylit interior
scenes using high dynamic range photography", CIE Lighting Quality and Energy Efficiency
(2016) (the sun's overflow and ND filters). Stumpfel et al., "Direct HDR capture of the sun
and sky", AFRIGRAPH 2004 (ND 3.0 filters for the solar disk).
"""

import math
from dataclasses import dataclass

import numpy as np

from ..errors import BadInputError
from ..geometry.field import pixel_geometry

__all__ = ["Overflow", "describe_overflow", "nd_exposure_factor", "repair_overflow_from_illuminance"]


@dataclass
class Overflow:
    """Pixels saturated in every frame.

    Attributes
    ----------
    pixels : int
    fraction : float
        Share of the image's pixels [–].
    solid_angle : float or None
        Their solid angle [sr] (None without camera geometry).
    centroid : (float, float)
        Their centre (row, col) [sensor px].
    luminance_lower_bound : float
        Smallest luminance they can have [cd·m⁻²] (the least-exposed frame saturates there).
    illuminance_lower_bound : float or None
        Their smallest contribution to the illuminance at the lens facing along the optical
        axis [lx].
    share_at_least : float or None
        That contribution over the map's illuminance with it [–]: the share of E_v at risk.
    repair : str or None
        How the overflow was filled in, if it was.
    repaired_luminance, repaired_uncertainty : float or None
        The luminance given to the overflow pixels and its standard uncertainty [cd·m⁻²]
        (the meter's uncertainty of the deficit; the spread of the real luminance over the
        region is unknown).
    """

    pixels: int
    fraction: float
    solid_angle: float | None
    centroid: tuple
    luminance_lower_bound: float
    illuminance_lower_bound: float | None
    share_at_least: float | None
    repair: str | None = None
    repaired_luminance: float | None = None
    repaired_uncertainty: float | None = None

    def to_dict(self):
        out = dict(self.__dict__)
        out["centroid"] = list(self.centroid)
        return out

    def message(self):
        where = f"around pixel ({self.centroid[0]:.0f}, {self.centroid[1]:.0f})"
        size = f"{self.solid_angle:.3g} sr" if self.solid_angle is not None else f"{self.pixels} px"
        risk = ("" if self.share_at_least is None else
                f"; at least {100 * self.share_at_least:.1f} % of the map's illuminance comes from it")
        return (f"luminous overflow: {100 * self.fraction:.2f} % of pixels ({size}) {where} are saturated in "
                f"every frame, luminance ≥ {self.luminance_lower_bound:.4g} cd/m² but unknown (NaN){risk}; "
                "repair with --illuminance and spots, or an --nd-filter frame")


def _weights(projection):
    geo = pixel_geometry(projection)
    cos_theta = np.nan_to_num(geo.directions[..., 2], nan=0.0)
    return geo.solid_angle, np.where(geo.valid & (cos_theta > 0), geo.solid_angle * cos_theta, 0.0)


def describe_overflow(saturated, luminance, projection, *, luminance_lower_bound, binning=1):
    """The :class:`Overflow` of a map, or None where nothing overflows.

    Parameters
    ----------
    saturated : ndarray of bool, (rows, cols)
        Pixels saturated in every frame.
    luminance : ndarray, (rows, cols)
        The map [cd·m⁻²] (NaN at the overflow).
    projection : Projection or None
    luminance_lower_bound : ndarray or float
        Per pixel (or one value) the luminance at which the least-exposed frame saturates [cd·m⁻²].
    binning : int
        Sensor pixels per map pixel (for the centroid in sensor px).
    """
    saturated = np.asarray(saturated, bool)
    if not saturated.any():
        return None
    bound = np.broadcast_to(np.asarray(luminance_lower_bound, np.float64), saturated.shape)
    rows, cols = np.nonzero(saturated)
    shift = (binning - 1) / 2.0
    centroid = (float(rows.mean() * binning + shift), float(cols.mean() * binning + shift))
    solid_angle = e_bound = share = None
    if projection is not None:
        omega, weight = _weights(projection)
        solid_angle = float(omega[saturated].sum())
        e_bound = float(np.sum(bound[saturated] * weight[saturated]))
        known = np.where(saturated | ~np.isfinite(luminance), 0.0, luminance)
        e_rest = float(np.sum(known * weight))
        share = e_bound / (e_rest + e_bound) if e_rest + e_bound > 0 else None
    return Overflow(pixels=int(saturated.sum()), fraction=float(saturated.mean()), solid_angle=solid_angle,
                    centroid=centroid, luminance_lower_bound=float(bound[saturated].min()),
                    illuminance_lower_bound=e_bound, share_at_least=share)


def repair_overflow_from_illuminance(luminance, saturated, projection, reading, overflow):
    """Fill the overflow with the luminance that makes the map's illuminance the meter's.

    Parameters
    ----------
    luminance : ndarray, (rows, cols)
        Calibrated map [cd·m⁻²], NaN at the overflow (not changed).
    saturated : ndarray of bool
    projection : Projection
        Must cover the hemisphere in front of the camera.
    reading : IlluminanceReading
    overflow : Overflow
        From :func:`describe_overflow` (updated with the repair).

    Returns
    -------
    ndarray
        The repaired map (float32).

    Raises
    ------
    BadInputError
        When the overflow lies behind the camera's hemisphere, or the meter's reading leaves
        less light for the overflow than its lower bound.
    """
    from .illuminance import hemisphere_illuminance

    e_known, _, _ = hemisphere_illuminance(luminance, projection, saturated=saturated)
    _, weight = _weights(projection)
    w = float(weight[saturated].sum())
    if not w > 0:
        raise BadInputError("the overflow lies outside the hemisphere the illuminance meter sees; it cannot repair it")
    deficit = reading.illuminance - e_known
    if deficit < overflow.illuminance_lower_bound:
        raise BadInputError(
            f"the illuminance reading {reading.illuminance:.4g} lx leaves {deficit:.4g} lx for the overflow, less "
            f"than its lower bound {overflow.illuminance_lower_bound:.4g} lx: the reading or the calibration is wrong"
        )
    value = deficit / w
    overflow.repair = f"illuminance {reading.illuminance:g} lx, deficit spread uniformly (evalglare -N)"
    overflow.repaired_luminance = float(value)
    overflow.repaired_uncertainty = float(reading.relative_uncertainty * reading.illuminance / w)
    return np.where(saturated, np.float32(value), luminance).astype(np.float32)


def nd_exposure_factor(stops):
    """Exposure multiplier 2^(−stops) of a neutral-density filter of ``stops`` stops [–]."""
    if not (isinstance(stops, (int, float)) and math.isfinite(stops) and stops >= 0):
        raise BadInputError(f"ND filter density must be a non-negative number of stops, got {stops!r}")
    return 2.0 ** (-float(stops))
