"""Per-source columns of evalglare's detailed table (``-d``) beyond L_s, ω_s and P.

For each grouped source evalglare 3.06 prints, besides its luminance, solid angle, position
index and centroid:

``Eglare``
    The illuminance its pixels give at the eye, Σ L·cos σ·ω over the source [lx].
``Lveil_cie``
    Its veiling luminance 10·Eglare/θ² [cd·m⁻²] (Stiles–Holladay;
    :func:`~lsadphoto.metrics.veiling.veiling_luminance_CIE146`), θ [deg] the angle from the
    line of sight to the pixel holding the source's pixel centroid.
``r_contrast``, ``r_dgp``
    Its share of DGP's glare term: with r = c2·log10(1 + L_s²·ω_s/P_s²/E_v^a3),
    r_contrast = r / (c2·log10(1 + Σ L²ω/P²/E_v^a3)) and r_dgp = r/DGP. As in evalglare the
    exponents of L, ω and P here are 2, 1, 2 whatever DGP coefficients are set; the sum in
    r_contrast runs over the sources *before* any zone split, and DGP is without the
    low-light correction and with the image's own E_v.
``zone``
    The zone the source lies in after the zone split (0 outside, 1, 2; see
    :mod:`~lsadphoto.metrics.regions`).

evalglare takes a source's angles at the pixel that holds its L·ω-weighted pixel centroid
(:func:`~lsadphoto.metrics.grouping.position_pixel_evalglare`), where the score takes its
position index and σ.

References
----------
Radiance ``src/util/evalglare.c`` v3.06 (the ``-d`` table: Eglare, Lveil_cie, glare_zone,
r_contrast, r_dgp; pictool.c: pict_get_sigma truncates its coordinates).
"""

import math

import numpy as np
from .._compiled import njit

from .veiling import veiling_luminance_CIE146

__all__ = ["source_illuminance", "glare_term_sum", "source_columns"]


@njit(cache=True, error_model="numpy", nogil=True,
      aot=tuple(f"void(int64[::1], boolean[::1], boolean, {L}[::1], {C}[::1], float64[::1], "
                "float64[::1])" for L in ("float32", "float64") for C in ("float32", "float64")))
def _source_illuminance(labels, labelled, use_labelled, luminance, cos_sigma, solid_angle, out):
    """``out[k − 1]`` += L·cos σ·ω (float64, in that order of products) of each pixel with
    label k ≤ out.size, in pixel order (where ``use_labelled``, of the ``labelled`` pixels
    only: the labels elsewhere are not read)."""
    n = out.size
    for i in range(labels.size):
        if use_labelled and not labelled[i]:
            continue
        k = labels[i]
        if 0 < k <= n:
            out[k - 1] += (np.float64(luminance[i]) * np.float64(cos_sigma[i])) \
                * np.float64(solid_angle[i])


def source_illuminance(labels, n_sources, luminance, cos_sigma, solid_angle, labelled=None):
    """Σ L·cos σ·ω over each source's pixels [lx] (evalglare ``Eglare``), float64, each
    source's pixels added in row-major order.

    Parameters
    ----------
    labels : ndarray of int, shape (rows, cols)
        Source number + 1 per pixel (0: none).
    n_sources : int
    luminance, cos_sigma, solid_angle : ndarray, shape (rows, cols)
        L [cd·m⁻²], cos σ [–], ω [sr].
    labelled : ndarray of bool, shape (rows, cols), optional
        Pixels that may carry a label (every pixel with one among them), e.g. the glare-source
        selection the labels were grouped from: only there are the labels read. A label map
        is mostly zeros that were never written (numpy's zeros come from the kernel), so
        reading all of it faults in a page per 512 pixels (24 MP: 45 000 faults, 0.05–0.07 s).

    Returns
    -------
    ndarray, shape (n_sources,)
    """
    def flat(array, kinds=(np.float32, np.float64)):
        array = np.asarray(array)
        if array.dtype not in kinds:
            array = array.astype(kinds[-1])
        return np.ascontiguousarray(array).reshape(-1)

    out = np.zeros(n_sources)
    if n_sources == 0:
        return out
    labels = flat(labels, (np.int64,))
    use = labelled is not None
    given = flat(labelled, (np.bool_,)) if use else np.zeros(0, dtype=bool)
    _source_illuminance(labels, given, use, flat(luminance), flat(cos_sigma),
                        flat(solid_angle, (np.float64,)), out)
    return out


def glare_term_sum(luminance, solid_angle, position_index):
    """Σ L_s²·ω_s/P_s² over sources [cd²·m⁻⁴·sr] (the sum in evalglare's r_contrast)."""
    L, w, P = (np.asarray(a, dtype=np.float64) for a in (luminance, solid_angle, position_index))
    return float(np.sum(L * L * w / (P * P)))


def source_columns(luminance, solid_angle, position_index, theta, illuminance, *,
                   vertical_illuminance, dgp, unsplit_sum, c2, a3, zones=None, age=None):
    """evalglare's per-source ``-d`` columns (see the module notes).

    Parameters
    ----------
    luminance, solid_angle, position_index : array_like, shape (n,)
        Per source L_s [cd·m⁻²], ω_s [sr], P_s [–].
    theta : array_like, shape (n,)
        Angle from the line of sight to each source's centroid pixel [rad].
    illuminance : array_like, shape (n,)
        Eglare of each source [lx] (:func:`source_illuminance`).
    vertical_illuminance : float
        The image's E_v [lx].
    dgp : float
        DGP of these sources without the low-light correction [–].
    unsplit_sum : float
        Σ L²ω/P² of the sources before the zone split (:func:`glare_term_sum`).
    c2, a3 : float
        DGP coefficients (evalglare ``-w``).
    zones : array_like of int, shape (n,), optional
        Zone of each source (0 when there are no zones).
    age : float, optional
        Observer age [years] for the CIE age factor of Lveil_cie.

    Returns
    -------
    list of dict
        ``{"Eglare", "Lveil_cie", "r_contrast", "r_dgp", "zone"}`` per source.
    """
    L, w, P = (np.asarray(a, dtype=np.float64) for a in (luminance, solid_angle, position_index))
    e_glare = np.asarray(illuminance, dtype=np.float64)
    veil = veiling_luminance_CIE146(e_glare, theta, age=age)
    e_v = float(vertical_illuminance)
    r = c2 * np.log10(1.0 + L * L * w / (P * P) / e_v**a3) if e_v > 0 else np.full(L.size, np.nan)
    total = c2 * math.log10(1.0 + unsplit_sum / e_v**a3) if e_v > 0 else math.nan
    zones = np.zeros(L.size, dtype=int) if zones is None else np.asarray(zones, dtype=int)
    with np.errstate(divide="ignore", invalid="ignore"):
        r_contrast = r / total
        r_dgp = r / dgp
    return [{"Eglare": float(e_glare[i]), "Lveil_cie": float(veil[i]),
             "r_contrast": float(r_contrast[i]), "r_dgp": float(r_dgp[i]), "zone": int(zones[i])}
            for i in range(L.size)]
