"""The observer's frame: line of sight, up vector, and the visual angles σ and τ.

Notation of FORMULAS.md: v̂ the line of sight, û the view-up (made perpendicular to v̂),
ĥ = v̂ × û (to the observer's right). For a direction d̂, σ is the angle from v̂ and τ the
angle around v̂ from the upward half-plane: τ = 0 straight above the line of sight, 90° to
the side, 180° straight below.

All vectors are in the camera frame of :mod:`~lsadphoto.geometry.base`: x to the right of
the image, y down the image, z along the optical axis.

References
----------
Radiance ``src/util/pictool.c`` (pict_get_sigma, pict_get_tau) and ``evalglare.c``; FORMULAS.md
"Notation". evalglare writes τ = arccos(û · normalize(d̂/cos σ − v̂)); the form used here,
the angle of d̂'s component perpendicular to v̂, is the same for σ < 90° and stays defined
behind the observer.
"""

import math
from dataclasses import dataclass

import numpy as np

from .._validation import check_array
from ..errors import BadInputError

__all__ = ["ON_AXIS", "ObserverFrame"]

#: Components perpendicular to v̂ below this (σ < 1e-15 rad) count as on the line of sight.
ON_AXIS = 1e-15


def _finite_angle(value, name):
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise BadInputError(f"{name} must be a number [deg], got {value!r}") from None
    if not math.isfinite(number):
        raise BadInputError(f"{name} must be finite, got {value!r}")
    return number


def orthonormal_pair(axis, second, *,
                    zero_message="line_of_sight must not be the zero vector",
                    parallel_message="up vector must not be parallel to the line of sight"):
    """Unit ``axis`` and the unit part of ``second`` perpendicular to it (Gram–Schmidt).

    Used for every frame of the package: the observer's line of sight and up, a camera's
    optical axis and up (:func:`lsadphoto.solver.camera_to_world`), a luminaire's nadir and
    C = 0 axis. Raises :class:`BadInputError` with ``zero_message`` for a zero ``axis`` and
    ``parallel_message`` when ``second`` is (nearly) parallel to it.
    """
    axis = np.asarray(axis, dtype=float)
    second = np.asarray(second, dtype=float)
    if np.linalg.norm(axis) == 0:
        raise BadInputError(zero_message)
    axis = axis / np.linalg.norm(axis)
    second = second - (second @ axis) * axis
    if np.linalg.norm(second) < 1e-9:
        raise BadInputError(parallel_message)
    return axis, second / np.linalg.norm(second)


@dataclass(frozen=True)
class ObserverFrame:
    """Line of sight and up vector in the camera frame (x right, y down, z forward).

    Parameters
    ----------
    line_of_sight : array_like, shape (3,)
        Default: the optical axis (0, 0, 1).
    up : array_like, shape (3,)
        Default: camera up (0, −1, 0). Made perpendicular to the line of sight.

    References
    ----------
    FORMULAS.md "Notation"; Radiance ``src/util/pictool.c`` (pict_get_sigma, pict_get_tau).

    Examples
    --------
    >>> frame = ObserverFrame.levelled(roll_deg=0.0, pitch_deg=10.0)
    >>> (np.round(frame.axes()[1], 6) + 0.0).tolist()  # the true vertical, camera coordinates
    [0.0, -0.984808, 0.173648]
    """

    line_of_sight: tuple = (0.0, 0.0, 1.0)
    up: tuple = (0.0, -1.0, 0.0)

    # --- constructors ----------------------------------------------------------------------

    @classmethod
    def from_pixel(cls, projection, row, col, *, up=None):
        """Frame whose line of sight passes through image point ``(row, col)`` [px].

        Parameters
        ----------
        projection : Projection
            Camera model giving the direction of the image point.
        row, col : float
            Image point [px], pixel-centre convention (may be fractional).
        up : array_like, shape (3,), optional
            Up vector in the camera frame; default camera up (0, −1, 0), or a
            :meth:`levelled` frame's ``up`` for a levelled horizon.

        Examples
        --------
        >>> from lsadphoto.geometry import PinholeProjection
        >>> cam = PinholeProjection(100.0, 100.0, 49.5, 49.5, 100, 100)
        >>> np.round(ObserverFrame.from_pixel(cam, 49.5, 149.5).line_of_sight, 6).tolist()
        [0.707107, 0.0, 0.707107]
        """
        d = np.asarray(projection.directions(float(row), float(col)), dtype=np.float64)
        if d.shape != (3,) or not np.all(np.isfinite(d)):
            raise BadInputError(f"image point (row {row}, col {col}) has no direction in this camera model")
        frame = cls(tuple(d.tolist()), cls.up if up is None else tuple(np.asarray(up, float).tolist()))
        frame.axes()  # fail early on a degenerate up vector
        return frame

    @classmethod
    def levelled(cls, *, roll_deg, pitch_deg, line_of_sight=None):
        """Frame with a levelled horizon, from the camera's roll and pitch [deg].

        The up vector is the true vertical expressed in the camera frame, so that the
        seam τ = 90° between the upper and lower field (FORMULAS.md "Notation") lies in the
        true horizontal plane through the line of sight, whatever the camera's tilt.

        Sign conventions (a camera at roll = pitch = 0 has its optical axis horizontal and
        the image rows horizontal):

        * ``pitch_deg`` > 0: camera tilted up, i.e. the optical axis points ``pitch_deg``
          above the horizontal (rotation about the camera's x axis).
        * ``roll_deg`` > 0: camera rotated clockwise about its optical axis as seen from
          behind the camera (the top of the camera moves to the right; the scene then
          appears rotated anticlockwise in the image). Roll is applied after pitch, as
          an orientation sensor or a level on the camera reports it.

        With c, s the cosine and sine, the true vertical in camera coordinates is
        ``(−s_roll·c_pitch, −c_roll·c_pitch, s_pitch)`` and the horizontal direction in front
        of the camera ``(s_roll·s_pitch, c_roll·s_pitch, c_pitch)``.

        Parameters
        ----------
        roll_deg, pitch_deg : float
            Camera roll and pitch [deg], signs as above.
        line_of_sight : array_like, shape (3,), optional
            Default: the horizontal direction in front of the camera (the optical axis
            projected onto the horizontal plane), i.e. a levelled observer looking straight
            ahead; then every horizontal direction has τ = 90°. Pass ``(0, 0, 1)`` to keep
            the optical axis as the line of sight with only the horizon levelled.

        References
        ----------
        ISO 1151-1 / DIN 9300 (aircraft attitude angles: pitch about the lateral axis,
        then roll about the longitudinal axis), used here for a camera.

        Examples
        --------
        >>> frame = ObserverFrame.levelled(roll_deg=0.0, pitch_deg=10.0)
        >>> sigma, tau = frame.angles(np.array([1.0, 0.0, 0.0]))  # true horizontal, right
        >>> round(float(np.degrees(tau)), 9)
        90.0
        """
        roll = math.radians(_finite_angle(roll_deg, "roll_deg"))
        pitch = math.radians(_finite_angle(pitch_deg, "pitch_deg"))
        sr, cr, sp, cp = math.sin(roll), math.cos(roll), math.sin(pitch), math.cos(pitch)
        up = (-sr * cp, -cr * cp, sp)
        if line_of_sight is None:
            if abs(cp) < 1e-9:
                raise BadInputError("pitch_deg = ±90°: the camera looks straight up or down and "
                                    "has no horizontal direction in front; give line_of_sight")
            line_of_sight = (sr * sp, cr * sp, cp)
        else:
            line_of_sight = tuple(
                check_array(line_of_sight, "line_of_sight", shape=(3,), finite=True, dtype=float).tolist())
        frame = cls(tuple(float(v) for v in line_of_sight), tuple(float(v) for v in up))
        frame.axes()
        return frame

    # --- serialisation ---------------------------------------------------------------------

    def to_dict(self):
        """JSON-serialisable form ``{"line_of_sight": [...], "up": [...]}``."""
        return {"line_of_sight": [float(v) for v in self.line_of_sight], "up": [float(v) for v in self.up]}

    @classmethod
    def from_dict(cls, data):
        """Inverse of :meth:`to_dict` (both keys optional, defaults as the constructor)."""
        if not isinstance(data, dict):
            raise BadInputError(f"observer frame description must be a dict, got {type(data).__name__}")
        unknown = set(data) - {"line_of_sight", "up"}
        if unknown:
            raise BadInputError(f"observer frame has unknown keys {sorted(unknown)}; valid: line_of_sight, up")
        values = {}
        for name in ("line_of_sight", "up"):
            if name in data:
                values[name] = tuple(check_array(data[name], name, shape=(3,), finite=True, dtype=float).tolist())
        frame = cls(**values)
        frame.axes()
        return frame

    # --- geometry --------------------------------------------------------------------------

    def axes(self):
        """Unit vectors (v̂, û, ĥ) of the frame."""
        v = check_array(self.line_of_sight, "line_of_sight", shape=(3,), finite=True, dtype=float)
        u = check_array(self.up, "up", shape=(3,), finite=True, dtype=float)
        v, u = orthonormal_pair(v, u)
        return v, u, np.cross(v, u)

    def _components(self, directions):
        d = np.asarray(directions, dtype=np.float64)
        if d.shape[-1:] != (3,):
            raise BadInputError(f"directions must have shape (..., 3), got {d.shape}")
        v, u, h = self.axes()
        return d @ v, d @ u, d @ h

    def angles(self, directions):
        """σ and τ [rad] of unit directions ``(..., 3)``; NaN directions give NaN.

        σ ∈ [0, π] (directions behind the observer have σ > π/2 and a defined τ);
        τ ∈ [0, π], and τ = 0 on the line of sight itself (where it is otherwise undefined).

        Examples
        --------
        >>> frame = ObserverFrame()
        >>> sigma, tau = frame.angles(np.array([[0.0, -1.0, 1.0], [1.0, 0.0, 1.0]]) / np.sqrt(2))
        >>> np.round(np.degrees(sigma), 6).tolist(), np.round(np.degrees(tau), 6).tolist()
        ([45.0, 45.0], [0.0, 90.0])
        """
        forward, up, side = self._components(directions)
        lateral = np.hypot(up, side)
        sigma = np.arctan2(lateral, forward)
        tau = np.arctan2(np.abs(side), up)
        with np.errstate(invalid="ignore"):
            tau = np.where(lateral < ON_AXIS, 0.0, tau)
        return sigma, tau

    def angular_coordinates(self, directions):
        """Plot coordinates (x, y) [rad] of directions around the line of sight.

        x = σ·sin τ, signed positive to the observer's right (along ĥ), and y = σ·cos τ,
        positive up: the azimuthal equidistant projection centred on the line of sight, in
        which the distance from the origin is σ and the polar angle from the y axis is τ.
        Directions behind the observer (σ > π/2) lie outside the circle of radius π/2;
        (0, 0) is the line of sight.

        Parameters
        ----------
        directions : array_like, shape (..., 3)
            Unit directions in the camera frame; NaN gives NaN.

        Returns
        -------
        x, y : numpy.ndarray
            Horizontal and vertical visual angle [rad].

        Examples
        --------
        >>> frame = ObserverFrame()
        >>> x, y = frame.angular_coordinates(np.array([[1.0, 0.0, 1.0], [0.0, 1.0, 1.0]]) / np.sqrt(2))
        >>> np.round(np.degrees(x), 6).tolist(), np.round(np.degrees(y), 6).tolist()
        ([45.0, 0.0], [0.0, -45.0])
        """
        forward, up, side = self._components(directions)
        lateral = np.hypot(up, side)
        sigma = np.arctan2(lateral, forward)
        with np.errstate(invalid="ignore", divide="ignore"):
            scale = np.where(lateral < ON_AXIS, 0.0, sigma / np.where(lateral < ON_AXIS, 1.0, lateral))
        return scale * side, scale * up
