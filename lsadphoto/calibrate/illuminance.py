"""Illuminance-meter calibration and cross-check of hemispherical luminance maps.

An illuminance meter held at the lens, its cosine-corrected head facing along the optical
axis, measures E = ∫ L cos θ dω over the hemisphere in front of the camera (for a horizontal
optical axis: the vertical illuminance E_v, the community's standard check of an HDR
photograph). A map that covers that hemisphere gives the same integral as Σ L·ω·cos θ over
its pixels, so

* without spot readings, the reading calibrates the map: k = E_meter / Σ Y·ω·cos θ;
* with spot readings, the reading cross-checks them: a disagreement between k_spot·Σ Y·ω·cos θ
  and E_meter beyond twice the combined standard uncertainty warns with both numbers.

The factor's uncertainty combines the meter's (a class B meter of DIN 5032-7: limits of
±7.5 % read as a rectangular distribution) with the map's noise over the hemisphere.

References
----------
Inanici, "Evaluation of high dynamic range photography as a luminance data acquisition
system", LR&T 38(2), 2006 (vertical illuminance from the fisheye image against a meter).
Pierson et al., LEUKOS 17(2), 2021, 140–169 (illuminance check of HDR luminance maps).
DIN 5032-7:2017 (classes of illuminance meters). JCGM 100:2008 (GUM) §4.3.7, §6.2 (k = 2).
"""

import math
import warnings
from dataclasses import dataclass

import numpy as np

from .._validation import check_positive
from ..errors import BadInputError, MetadataWarning, SaturationWarning
from ..geometry.field import pixel_geometry

__all__ = ["IlluminanceReading", "IlluminanceCheck", "hemisphere_illuminance", "calibrate_illuminance",
           "cross_check_illuminance", "ILLUMINANCE_METER_RELATIVE_STANDARD_UNCERTAINTY"]

#: Class B illuminance meter (DIN 5032-7): total error limits ±7.5 %, read as the bounds of a
#: rectangular distribution → relative standard uncertainty 0.075/√3 (GUM §4.3.7).
ILLUMINANCE_METER_RELATIVE_STANDARD_UNCERTAINTY = 0.075 / math.sqrt(3.0)
#: Share of the cosine-weighted hemisphere (π sr) a map must cover to be integrated [–]; the
#: ideal fisheye's centre rule leaves out < 1e-4 of a 180° circle (geometry/fisheye.py).
HEMISPHERE_COVERAGE = 0.995
#: Coverage factor of the cross-check (GUM §6.2: k = 2, about 95 %).
CROSS_CHECK_COVERAGE_FACTOR = 2.0


@dataclass(frozen=True)
class IlluminanceReading:
    """An illuminance-meter reading at the lens, the head facing along the optical axis.

    Attributes
    ----------
    illuminance : float
        The reading [lx].
    relative_uncertainty : float
        Relative standard uncertainty of the meter [–].
    """

    illuminance: float
    relative_uncertainty: float = ILLUMINANCE_METER_RELATIVE_STANDARD_UNCERTAINTY

    def __post_init__(self):
        check_positive(self.illuminance, "illuminance reading")
        check_positive(self.relative_uncertainty, "illuminance meter uncertainty")


@dataclass
class IlluminanceCheck:
    """Result of an illuminance calibration or cross-check.

    Attributes
    ----------
    meter : float
        The reading [lx].
    map_illuminance : float
        Σ L·ω·cos θ of the map [lx] (with the factor finally used).
    factor : float
        Calibration factor the reading implies [cd·m⁻² per relative unit].
    relative_uncertainty : float
        Relative standard uncertainty of that factor [–] (meter and map noise).
    saturated_share : float
        Share of the map's cosine-weighted solid angle that is saturated (its light is missing
        from the integral) [–].
    agrees : bool or None
        Cross-check only: |map − meter| ≤ 2·u_c.
    """

    meter: float
    map_illuminance: float
    factor: float
    relative_uncertainty: float
    saturated_share: float
    agrees: bool | None = None

    def to_dict(self):
        return {k: getattr(self, k) for k in ("meter", "map_illuminance", "factor", "relative_uncertainty",
                                              "saturated_share", "agrees")}


def hemisphere_illuminance(relative, projection, *, relative_variance=None, saturated=None):
    """(E, u_E, saturated share): Σ Y·ω·cos θ over the hemisphere in front of the camera.

    Parameters
    ----------
    relative : ndarray, (rows, cols)
        Relative (or absolute) luminance; NaN where unknown.
    projection : Projection
        Geometry of the map; it must cover the hemisphere (e.g. a 180° fisheye).
    relative_variance : ndarray, optional
        Per-pixel variance of ``relative`` (noise), for u_E.
    saturated : ndarray of bool, optional

    Returns
    -------
    E : float
        [lx] when ``relative`` is in cd·m⁻².
    u_E : float
        Standard uncertainty of E from the pixel noise (independent pixels).
    saturated_share : float
    """
    if projection is None:
        raise BadInputError("an illuminance reading needs the camera geometry (a hemispherical projection)")
    geo = pixel_geometry(projection)
    cos_theta = np.nan_to_num(geo.directions[..., 2], nan=0.0)
    weight = np.where(geo.valid & (cos_theta > 0), geo.solid_angle * cos_theta, 0.0)
    coverage = float(weight.sum()) / math.pi
    if coverage < HEMISPHERE_COVERAGE:
        raise BadInputError(f"an illuminance reading needs a hemispherical map: this view covers "
                            f"{100 * coverage:.1f} % of the cosine-weighted hemisphere (a 180° fisheye covers all)")
    values = np.asarray(relative, dtype=np.float64)
    unknown = ~np.isfinite(values)
    if saturated is not None:
        unknown |= np.asarray(saturated, bool)
    share = float(weight[unknown].sum() / weight.sum())
    e = float(np.sum(np.where(unknown, 0.0, values) * weight))
    u = 0.0
    if relative_variance is not None:
        var = np.nan_to_num(np.asarray(relative_variance, np.float64), nan=0.0)
        u = float(np.sqrt(np.sum(np.where(unknown, 0.0, var) * weight**2)))
    return e, u, share


def _warn_saturated(share):
    if share > 0:
        warnings.warn(f"{100 * share:.2f} % of the cosine-weighted hemisphere is saturated: its light is missing "
                      "from the map's illuminance, which is therefore low", SaturationWarning, stacklevel=3)


def calibrate_illuminance(relative, projection, reading, *, relative_variance=None, saturated=None):
    """Calibration factor k = E_meter / Σ Y·ω·cos θ of a hemispherical map.

    Returns
    -------
    IlluminanceCheck
    """
    e, u_e, share = hemisphere_illuminance(relative, projection, relative_variance=relative_variance,
                                           saturated=saturated)
    if not e > 0:
        raise BadInputError("the map's illuminance is not positive; nothing to calibrate")
    _warn_saturated(share)
    factor = reading.illuminance / e
    u = math.hypot(reading.relative_uncertainty, u_e / e)
    return IlluminanceCheck(meter=reading.illuminance, map_illuminance=reading.illuminance, factor=factor,
                            relative_uncertainty=u, saturated_share=share)


def cross_check_illuminance(relative, projection, reading, *, factor, factor_uncertainty,
                            relative_variance=None, saturated=None):
    """Compare k·Σ Y·ω·cos θ (spot-calibrated) with the meter; warn beyond 2·u_c.

    Parameters
    ----------
    factor, factor_uncertainty : float
        The spot calibration's factor and its relative standard uncertainty.

    Returns
    -------
    IlluminanceCheck
        ``agrees`` is False when they disagree (a :class:`MetadataWarning` names both).
    """
    e, u_e, share = hemisphere_illuminance(relative, projection, relative_variance=relative_variance,
                                           saturated=saturated)
    _warn_saturated(share)
    e_map = factor * e
    u_map = math.hypot(factor_uncertainty, u_e / e if e > 0 else 0.0)
    u_c = math.hypot(u_map, reading.relative_uncertainty)
    agrees = abs(e_map / reading.illuminance - 1.0) <= CROSS_CHECK_COVERAGE_FACTOR * u_c
    if not agrees:
        warnings.warn(f"illuminance check fails: the spot-calibrated map gives {e_map:.4g} lx, the meter "
                      f"{reading.illuminance:.4g} lx ({100 * (e_map / reading.illuminance - 1):+.1f} %, beyond "
                      f"2 × the combined uncertainty {100 * u_c:.1f} %)", MetadataWarning, stacklevel=2)
    return IlluminanceCheck(meter=reading.illuminance, map_illuminance=e_map,
                            factor=reading.illuminance / e if e > 0 else math.nan,
                            relative_uncertainty=math.hypot(reading.relative_uncertainty, u_e / e if e > 0 else 0.0),
                            saturated_share=share, agrees=agrees)
