"""Radiance ``xform`` transforms: the option words parsed into 4×4 matrices, arrays expanded.

``xform`` (and the transform words Radiance appends to the string arguments of patterns)
applies ``-t x y z`` (translate), ``-rx``/``-ry``/``-rz`` θ [deg] (rotate about an axis,
counter-clockwise looking down the axis, right-handed), ``-s f`` (uniform scale),
``-mx``/``-my``/``-mz`` (mirror in the yz, xz, xy plane) in the order given, each after the
previous ones. ``-a n`` makes n copies, the k-th (k = 0…n−1) with the transform words that
follow (up to the next ``-a`` or ``-i``) applied k times; ``-i n`` applies the words that
follow n times in every copy. Nested arrays give every combination of their copies.

References
----------
Radiance manual page ``xform(1)``; Radiance ``src/common/xf.c`` (transform words and their
order).
"""

import itertools
import math

import numpy as np

from ...errors import BadInputError

__all__ = ["TRANSFORM_WORDS", "Transform", "parse_transform"]

#: Transform option words and how many numbers follow each.
TRANSFORM_WORDS = {"-t": 3, "-rx": 1, "-ry": 1, "-rz": 1, "-s": 1, "-mx": 0, "-my": 0, "-mz": 0,
                   "-a": 1, "-i": 1}


class Transform:
    """An affine map p ↦ A p + b with A = s·Q (Q orthogonal, s > 0 a uniform scale).

    Examples
    --------
    >>> t = parse_transform(["-rz", "90", "-t", "1", "0", "0"])[0][1]
    >>> t.point([1, 0, 0]).round(12).tolist(), t.scale, t.mirrored
    ([1.0, 1.0, 0.0], 1.0, False)
    """

    def __init__(self, matrix=None):
        self.matrix = np.eye(4) if matrix is None else np.asarray(matrix, float)
        linear = self.matrix[:3, :3]
        det = float(np.linalg.det(linear))
        #: Uniform scale factor s [–].
        self.scale = abs(det) ** (1.0 / 3.0)
        #: Whether the map reverses handedness (an odd number of mirrors).
        self.mirrored = det < 0

    def __matmul__(self, other):
        """The map that applies ``other`` first, then ``self``."""
        return Transform(self.matrix @ other.matrix)

    def point(self, p):
        """Transformed points ``(..., 3)`` [m]."""
        p = np.asarray(p, float)
        return p @ self.matrix[:3, :3].T + self.matrix[:3, 3]

    def vector(self, v):
        """Transformed direction vectors ``(..., 3)`` (not normalised)."""
        return np.asarray(v, float) @ self.matrix[:3, :3].T

    def inverse_direction(self, v):
        """Unit directions ``(..., 3)`` in the untransformed frame of world directions ``v``."""
        local = np.asarray(v, float) @ np.linalg.inv(self.matrix[:3, :3]).T
        return local / np.linalg.norm(local, axis=-1, keepdims=True)


def _op_matrix(word, values):
    m = np.eye(4)
    if word == "-t":
        m[:3, 3] = values
    elif word == "-s":
        m[:3, :3] *= values[0]
    elif word in ("-mx", "-my", "-mz"):
        k = "xyz".index(word[2])
        m[k, k] = -1.0
    else:  # rotation
        a = math.radians(values[0])
        c, s = math.cos(a), math.sin(a)
        i, j = {"-rx": (1, 2), "-ry": (2, 0), "-rz": (0, 1)}[word]
        m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
    return m


def parse_transform(words, where="xform"):
    """The copies ``[(index, Transform), …]`` that transform words make (one without ``-a``).

    ``index`` is the tuple of array indices of the copy (empty without ``-a``). Any word
    that is not a transform word raises :class:`BadInputError` naming it and ``where``.
    """
    groups = [["once", 1, np.eye(4)]]
    k = 0
    words = list(words)
    while k < len(words):
        word = words[k]
        if word not in TRANSFORM_WORDS:
            raise BadInputError(f"{where}: {word!r} is not a transform option "
                                f"(valid: {', '.join(TRANSFORM_WORDS)})")
        n = TRANSFORM_WORDS[word]
        try:
            values = [float(v) for v in words[k + 1:k + 1 + n]]
        except ValueError:
            values = []
        if len(values) != n or not all(math.isfinite(v) for v in values):
            raise BadInputError(f"{where}: {word} needs {n} number(s)")
        k += 1 + n
        if word in ("-a", "-i"):
            count = int(values[0])
            if count != values[0] or count < (1 if word == "-a" else 0):
                raise BadInputError(f"{where}: {word} needs a whole number"
                                    f"{' ≥ 1' if word == '-a' else ' ≥ 0'}, got {values[0]:g}")
            groups.append(["array" if word == "-a" else "iterate", count, np.eye(4)])
        else:
            if word == "-s" and not values[0] != 0:
                raise BadInputError(f"{where}: -s needs a non-zero scale factor")
            groups[-1][2] = _op_matrix(word, values) @ groups[-1][2]
    arrays = [g for g in groups if g[0] == "array"]
    copies = []
    for index in itertools.product(*(range(g[1]) for g in arrays)):
        matrix, a = np.eye(4), 0
        for kind, count, step in groups:
            if kind == "array":
                count = index[a]
                a += 1
            matrix = np.linalg.matrix_power(step, count) @ matrix
        copies.append((index, Transform(matrix)))
    return copies
