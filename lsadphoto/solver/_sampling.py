"""Random streams and the elementary sampling routines of the solver.

Streams are derived from ``(seed, purpose, key…)`` through :class:`numpy.random.SeedSequence`
and the counter-based Philox bit generator. The keys are *fixed-size* blocks of work (a
block of light chains, a block of pixels of one batch), never the size of a processing
chunk, so results do not depend on how the work is chunked or scheduled.

References
----------
Salmon, J. K. et al. (2011). Parallel random numbers: as easy as 1, 2, 3. *SC '11*
(Philox). Pharr, M., Jakob, W., Humphreys, G. (2023). *Physically Based Rendering*, 4th ed.,
§8.3 (samplers keyed on pixel and sample index), §A.5 (cosine-weighted hemisphere).
"""

import math

import numpy as np

#: Stream purposes (the first spawn key): light chains, near-field rays, path tracing,
#: gather subsampling, direct-light samples, surface-cache node draws, distant-source samples.
_PURPOSE = {"chains": 1, "near": 2, "path": 3, "gather": 4, "direct": 5, "cache": 6, "distant": 7}


def stream(seed, purpose, *keys):
    """A Philox generator for ``(seed, purpose, *keys)`` (non-negative integers)."""
    ss = np.random.SeedSequence(entropy=int(seed), spawn_key=(_PURPOSE[purpose], *map(int, keys)))
    return np.random.Generator(np.random.Philox(ss))


class GroupStreams:
    """Draws for rows sorted by group, each group from its own generator.

    ``counts`` (set before each use) holds the number of live rows per group; each method
    concatenates each generator's draws, so a group's numbers do not depend on which other
    groups share the array (work on many blocks at once draws what one block at a time
    would).
    """

    def __init__(self, gens):
        self.gens = gens
        self.counts = np.zeros(len(gens), dtype=np.int64)

    def random(self, size):
        shape = (size,) if np.isscalar(size) else tuple(size)
        rest = shape[1:]
        return np.concatenate([g.random((int(c), *rest)) for g, c in zip(self.gens, self.counts)])

    def integers(self, high, per_row):
        """Flat integers: for each group g, ``counts[g]`` rows of ``per_row[g]`` integers in
        [0, ``high[g]``), row by row (groups with no rows or no integers draw nothing)."""
        parts = [g.integers(0, int(h), size=(int(c), int(k))).ravel()
                 for g, h, k, c in zip(self.gens, high, per_row, self.counts) if c > 0 and k > 0]
        return np.concatenate(parts) if parts else np.zeros(0, np.int64)


def orthonormal_basis(n):
    """Two unit vectors ``(t, b)`` completing unit normals ``n`` ``(k, 3)`` (Duff et al. 2017)."""
    sign = np.where(n[:, 2] >= 0, 1.0, -1.0)
    a = -1.0 / (sign + n[:, 2])
    b = n[:, 0] * n[:, 1] * a
    t = np.stack([1.0 + sign * n[:, 0] ** 2 * a, sign * b, -sign * n[:, 0]], axis=1)
    bb = np.stack([b, sign + n[:, 1] ** 2 * a, -n[:, 1]], axis=1)
    return t, bb


def cosine_directions(normals, u):
    """Cosine-weighted directions about unit ``normals`` ``(k, 3)`` from uniforms ``u`` ``(k, 2)``.

    Density cos θ/π [sr⁻¹] (Malley's method).
    """
    r = np.sqrt(u[:, 0])
    phi = 2.0 * math.pi * u[:, 1]
    x, y = r * np.cos(phi), r * np.sin(phi)
    z = np.sqrt(np.maximum(0.0, 1.0 - u[:, 0]))
    t, b = orthonormal_basis(normals)
    return x[:, None] * t + y[:, None] * b + z[:, None] * normals


def triangle_points(triangles, u):
    """Uniform points on triangles ``(k, 3, 3)`` from uniforms ``u`` ``(k, 2)``."""
    su = np.sqrt(u[:, 0])
    b0 = 1.0 - su
    b1 = u[:, 1] * su
    b2 = 1.0 - b0 - b1
    return b0[:, None] * triangles[:, 0] + b1[:, None] * triangles[:, 1] + b2[:, None] * triangles[:, 2]
