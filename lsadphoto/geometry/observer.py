"""The observer's frame: line of sight, up vector, and the visual angles σ and τ.

Notation of FORMULAS.md: v̂ the line of sight, û the view-up (made perpendicular to v̂),
ĥ = v̂ × û (to the observer's right). For a direction d̂, σ is the angle from v̂ and τ the
angle around v̂ from the upward half-plane: τ = 0 straight above the line of sight, 90° to
the side, 180° straight below.

References
----------
Radiance ``src/util/pictool.c`` (pict_get_sigma, pict_get_tau) and ``evalglare.c``; FORMULAS.md
"Notation". evalglare writes τ = arccos(û · normalize(d̂/cos σ − v̂)); the form used here,
the angle of d̂'s component perpendicular to v̂, is the same for σ < 90° and stays defined
behind the observer.
"""

from dataclasses import dataclass

import numpy as np

from .._validation import check_array
from ..errors import BadInputError


@dataclass(frozen=True)
class ObserverFrame:
    """Line of sight and up vector in the camera frame (x right, y down, z forward).

    Parameters
    ----------
    line_of_sight : array_like, shape (3,)
        Default: the optical axis (0, 0, 1).
    up : array_like, shape (3,)
        Default: camera up (0, −1, 0). Made perpendicular to the line of sight.
    """

    line_of_sight: tuple = (0.0, 0.0, 1.0)
    up: tuple = (0.0, -1.0, 0.0)

    def axes(self):
        """Unit vectors (v̂, û, ĥ) of the frame."""
        v = check_array(self.line_of_sight, "line_of_sight", shape=(3,), finite=True, dtype=float)
        u = check_array(self.up, "up", shape=(3,), finite=True, dtype=float)
        if np.linalg.norm(v) == 0:
            raise BadInputError("line_of_sight must not be the zero vector")
        v = v / np.linalg.norm(v)
        u = u - (u @ v) * v
        if np.linalg.norm(u) < 1e-9:
            raise BadInputError("up vector must not be parallel to the line of sight")
        u = u / np.linalg.norm(u)
        return v, u, np.cross(v, u)

    def angles(self, directions):
        """σ and τ [rad] of unit directions ``(..., 3)``; NaN directions give NaN.

        Examples
        --------
        >>> frame = ObserverFrame()
        >>> sigma, tau = frame.angles(np.array([[0.0, -1.0, 1.0], [1.0, 0.0, 1.0]]) / np.sqrt(2))
        >>> np.round(np.degrees(sigma), 6).tolist(), np.round(np.degrees(tau), 6).tolist()
        ([45.0, 45.0], [0.0, 90.0])
        """
        d = np.asarray(directions, dtype=np.float64)
        v, u, h = self.axes()
        forward = d @ v
        up = d @ u
        side = d @ h
        lateral = np.hypot(up, side)
        sigma = np.arctan2(lateral, forward)
        tau = np.arctan2(np.abs(side), up)
        return sigma, tau
