"""Tabulated luminous intensity distributions I(C, γ): evaluation, flux and sampling.

Every non-Lambertian luminaire of the solver (isotropic points, callables, photometric
files) is turned into one :class:`IntensityTable`: intensities [cd] on a grid of C-planes
(0…2π) and polar angles γ (0…π, γ = 0 along the luminaire's nadir axis), bilinearly
interpolated between grid points. The luminous flux of that interpolant is computed
exactly (cell by cell, in closed form), and emission directions are sampled from a
piecewise-constant density over the grid cells, with the sampling weight
I(ω)/(Φ·p(ω)) carried by the chain, so the sampling is unbiased for the interpolant
whatever the grid.

Local frame of a luminaire: ``nadir`` (γ = 0), ``length_axis`` (C = 0, γ = 90°) and
C = 90° along ``zenith × length_axis`` (counter-clockwise seen from above, as in
EN 13032-1 C-planes).

References
----------
EN 13032-1:2004+A1:2012, Light and lighting — Measurement and presentation of photometric
data of lamps and luminaires, Part 1 (C-γ coordinate system).
Marchuk, G. I. et al. (1980), *Monte Carlo Methods in Atmospheric Optics*, Springer,
ch. 2 (sampling of source distributions, weights).
"""

import math

import numpy as np

from .._validation import check_array
from ..errors import BadInputError
from ..geometry.observer import orthonormal_pair

__all__ = ["IntensityTable", "luminaire_frame"]


def luminaire_frame(nadir, length_axis):
    """Orthonormal axes (e_C0, e_C90, e_nadir) of a luminaire, as rows of a 3×3 array.

    ``nadir`` is the γ = 0 direction, ``length_axis`` the C = 0 half-plane (made
    perpendicular to the nadir).
    """
    n = check_array(nadir, "nadir", shape=(3,), finite=True, dtype=float)
    a = check_array(length_axis, "length_axis", shape=(3,), finite=True, dtype=float)
    n, a = orthonormal_pair(n, a, zero_message="luminaire nadir axis must not be the zero vector",
                            parallel_message="luminaire length axis must not be parallel to its "
                                             "nadir axis")
    b = np.cross(-n, a)  # zenith × C0
    return np.stack([a, b, n])


class IntensityTable:
    """Luminous intensity [cd] on a (C, γ) grid, bilinear in between.

    Parameters
    ----------
    c_angles : array_like, shape (nc,)
        C-plane angles [rad], increasing, from 0 to 2π inclusive (a full turn; the last
        column must equal the first for a continuous distribution — it is used as given).
    gamma_angles : array_like, shape (ng,)
        Polar angles from the nadir [rad], increasing, from 0 to π inclusive.
    intensity : array_like, shape (nc, ng)
        Luminous intensity [cd], finite and non-negative.
    """

    def __init__(self, c_angles, gamma_angles, intensity):
        c = check_array(c_angles, "c_angles", ndim=1, finite=True, dtype=float)
        g = check_array(gamma_angles, "gamma_angles", ndim=1, finite=True, dtype=float)
        i = check_array(intensity, "intensity", shape=(c.size, g.size), finite=True, dtype=float)
        if c.size < 2 or g.size < 2 or np.any(np.diff(c) <= 0) or np.any(np.diff(g) <= 0):
            raise BadInputError("intensity grid angles must be increasing with ≥ 2 values each")
        if abs(c[0]) > 1e-9 or abs(c[-1] - 2 * math.pi) > 1e-9:
            raise BadInputError("C angles must run from 0 to 2π")
        if abs(g[0]) > 1e-9 or abs(g[-1] - math.pi) > 1e-9:
            raise BadInputError("γ angles must run from 0 to π")
        if np.any(i < 0):
            raise BadInputError("luminous intensity must not be negative")
        self.c_angles, self.gamma_angles, self.intensity = c, g, i
        # Exact flux of each cell of the bilinear interpolant: average over C of the two
        # C-edges (linear in C), then ∫(α + β(γ − γ0)) sin γ dγ in closed form.
        g0, g1 = g[:-1], g[1:]
        dc = np.diff(c)[:, None]
        left = 0.5 * (i[:-1, :-1] + i[1:, :-1])   # I at γ0, averaged over C
        right = 0.5 * (i[:-1, 1:] + i[1:, 1:])    # I at γ1
        beta = (right - left) / (g1 - g0)
        m0 = np.cos(g0) - np.cos(g1)
        m1 = -(g1 - g0) * np.cos(g1) + np.sin(g1) - np.sin(g0)
        self._cell_flux = dc * (left * m0 + beta * m1)
        self.luminous_flux = float(self._cell_flux.sum())
        if not self.luminous_flux > 0:
            raise BadInputError("intensity distribution emits no flux")
        # Sampling density: piecewise constant, cell probability ∝ the largest corner
        # value × cell solid angle, so that p > 0 wherever the interpolant is > 0.
        peak = np.maximum.reduce([i[:-1, :-1], i[1:, :-1], i[:-1, 1:], i[1:, 1:]])
        self._cell_omega = dc * m0
        mass = peak * self._cell_omega
        self._cell_prob = (mass / mass.sum()).ravel()
        self._cdf = np.cumsum(self._cell_prob)
        self._cdf[-1] = 1.0

    @classmethod
    def isotropic(cls, intensity):
        """A constant intensity [cd] in all directions (flux 4π·I)."""
        value = float(intensity)
        if not (math.isfinite(value) and value > 0):
            raise BadInputError(f"intensity must be a finite positive number, got {intensity!r}")
        return cls([0.0, 2 * math.pi], [0.0, math.pi], np.full((2, 2), value))

    @classmethod
    def from_function(cls, function, *, c_step_deg=5.0, gamma_step_deg=1.0):
        """Tabulate ``function(c, gamma) -> intensity [cd]`` (radians, numpy-vectorised).

        The grid steps [deg] are keyword options; the interpolant of the tabulated values
        is what the solver then uses (evaluation and flux alike).
        """
        c = np.radians(np.linspace(0.0, 360.0, round(360.0 / c_step_deg) + 1))
        g = np.radians(np.linspace(0.0, 180.0, round(180.0 / gamma_step_deg) + 1))
        cc, gg = np.meshgrid(c, g, indexing="ij")
        try:
            values = np.broadcast_to(np.asarray(function(cc, gg), dtype=float), cc.shape).copy()
        except Exception as exc:  # noqa: BLE001 - any failure of a user callable becomes one line
            raise BadInputError(f"intensity function failed on a (C, γ) grid: {exc}") from None
        values[-1] = values[0]
        return cls(c, g, values)

    def __call__(self, c, gamma):
        """Interpolated intensity [cd] at C, γ [rad] (any broadcastable shapes)."""
        c = np.mod(np.asarray(c, float), 2 * math.pi)
        gamma = np.clip(np.asarray(gamma, float), 0.0, math.pi)
        ci = np.clip(np.searchsorted(self.c_angles, c, side="right") - 1, 0, self.c_angles.size - 2)
        gi = np.clip(np.searchsorted(self.gamma_angles, gamma, side="right") - 1, 0,
                     self.gamma_angles.size - 2)
        c0, c1 = self.c_angles[ci], self.c_angles[ci + 1]
        g0, g1 = self.gamma_angles[gi], self.gamma_angles[gi + 1]
        tc = (c - c0) / (c1 - c0)
        tg = (gamma - g0) / (g1 - g0)
        i = self.intensity
        return ((1 - tc) * (1 - tg) * i[ci, gi] + tc * (1 - tg) * i[ci + 1, gi]
                + (1 - tc) * tg * i[ci, gi + 1] + tc * tg * i[ci + 1, gi + 1])

    def local_angles(self, directions, frame):
        """C, γ [rad] of world directions ``(..., 3)`` in a luminaire ``frame`` (rows)."""
        local = np.asarray(directions, float) @ frame.T
        gamma = np.arccos(np.clip(local[..., 2], -1.0, 1.0))
        c = np.mod(np.arctan2(local[..., 1], local[..., 0]), 2 * math.pi)
        return c, gamma

    def evaluate(self, directions, frame):
        """Intensity [cd] in world directions ``(..., 3)`` for a luminaire ``frame``."""
        return self(*self.local_angles(directions, frame))

    def sample(self, rng, n, frame):
        """``n`` world directions and their sampling weights I(ω)/(Φ·p(ω)) [–].

        The weight has mean 1 under the sampling density; it is exactly 1 where the
        intensity is constant over a cell. ``frame`` is one luminaire frame (3, 3) or one
        per direction (n, 3, 3) (rows e_C0, e_C90, e_nadir).
        """
        local, weight = self.sample_local(rng, n)
        frame = np.asarray(frame, float)
        if frame.ndim == 3:
            return np.einsum("nk,nkj->nj", local, frame), weight
        return local @ frame, weight

    def sample_local(self, rng, n):
        """``n`` directions in the luminaire's own frame and their weights (see :meth:`sample`)."""
        cell = np.minimum(np.searchsorted(self._cdf, rng.random(n), side="right"),
                          self._cdf.size - 1)
        ng = self.gamma_angles.size - 1
        ci, gi = np.divmod(cell, ng)
        c0, c1 = self.c_angles[ci], self.c_angles[ci + 1]
        cos0, cos1 = np.cos(self.gamma_angles[gi]), np.cos(self.gamma_angles[gi + 1])
        u = rng.random((2, n))
        c = c0 + u[0] * (c1 - c0)
        cos_g = cos0 + u[1] * (cos1 - cos0)
        sin_g = np.sqrt(np.maximum(0.0, 1.0 - cos_g * cos_g))
        local = np.stack([sin_g * np.cos(c), sin_g * np.sin(c), cos_g], axis=-1)
        pdf = self._cell_prob[cell] / self._cell_omega.ravel()[cell]
        gamma = np.arccos(np.clip(cos_g, -1.0, 1.0))
        weight = self(c, gamma) / (self.luminous_flux * pdf)
        return local, weight

    def to_arrays(self):
        """``(c_angles, gamma_angles, intensity)`` for storage."""
        return self.c_angles, self.gamma_angles, self.intensity
