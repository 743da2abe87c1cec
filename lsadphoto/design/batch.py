"""Evaluating many designs at once from the candidates' precomputed parts, exactly.

A design's map is L = Σ_c w_c·L_c (:func:`~lsadphoto.design.superpose`); this module gives,
for a block of designs (a weight matrix), the numbers :func:`~lsadphoto.metrics.score_map`
would give for each superposed map with the design search's settings (score_map's defaults,
noise resampling off) — without forming the maps. What makes that possible, metric by
metric:

* **E_v** = Σ L·cos σ·ω and the field means are linear: one product of the weights with the
  candidates' sums. The **grids** (Ē, E_min, U₀ and Ē's standard error) likewise.
* **Glare-source pixels** (L > 2000 cd·m⁻²) can only be pixels whose upper bound over all
  designs — the sum over positions of the brightest choice there — exceeds the threshold:
  a few hundred pixels (the luminaires' images). On those the design's luminance is formed
  exactly as :func:`superpose` forms it (float64 sum in the same order, rounded to float32),
  so the source mask, E_dir, L_b = (E_v − E_dir)/π and the pixel-UGR sum ΣL²ω/P² are
  score_map's.
* **Grouped sources** (evalglare's single linkage at r/2 with peak extraction): the possible
  source pixels fall into linkage components that never join one another, whatever the
  design; a design's groups are the groups of its source pixels inside each component. Those
  depend only on which pixels are sources and which are peaks, so each component's grouping
  is computed once per pattern by :func:`~lsadphoto.metrics.grouping.group_sources_evalglare`
  itself and reused (a handful of patterns per component). The groups' sums, centroids,
  the position index at evalglare's centroid pixel, grouped UGR and DGP follow per design.
* **Q** needs the angular gradient g = √(a² + b²) of every evaluated pixel, with (a, b)
  linear in the map (:func:`~lsadphoto.metrics.quality.gradient_components`), and keeps the
  pixels with g·α ≥ N·ΔL(L̄). Exact pruning: by the triangle inequality
  g ≤ Σ_c w_c·g_c, so a tile of 8 × 8 pixels is skipped when Σ_c w_c·max_tile g_c is below
  the design's cut (with a 10⁻⁵ margin for rounding); in the remaining tiles (a, b) are
  summed and the cut applied pixel by pixel.

Equality with score_map is tested on random designs (``tests/test_design_batch.py``): the
sources' luminance is bit-identical; the linear parts differ by float rounding (relative
10⁻⁷: score_map sums the float32-rounded map, this sums the candidates' sums); Q's
gradient components likewise, so a pixel whose g·α lies within 10⁻⁶ of the cut could be
decided differently (not seen in the tests).

Only score_map's default settings are supported (the design search uses no other).

References
----------
Budak et al. (seed paper, §5, the inverse problem); CIE 117:1995 (UGR); Wienold &
Christoffersen (2006) (DGP); Radiance ``src/util/evalglare.c`` (grouping); FORMULAS.md §3–5.
"""

import math

import numpy as np
from numba import njit, prange

from ..errors import BadInputError
from ..geometry import ObserverFrame, position_index
from ..geometry.field import pixel_geometry, visual_field
from ..metrics.adrian import threshold_luminance_difference
from ..metrics.glare_indices import dgp_coefficients
from ..metrics.grouping import DEFAULT_PEAK_LUMINANCE, DEFAULT_SEARCH_ANGLE, group_sources_evalglare
from ..metrics.quality import gradient_components, q_Budak2021
from ..metrics.sources import DEFAULT_SOURCE_THRESHOLD

__all__ = ["BatchEvaluator"]

#: score_map's defaults that the batch evaluator reproduces.
_N_THRESHOLDS = 50.0
_SIZE_ARCMIN = 10.0
_ALPHA = _SIZE_ARCMIN * math.pi / (180.0 * 60.0)
_THRESHOLD_OPTIONS = {"exposure_time": 2.0, "age": 23}
_DGP = dgp_coefficients("evalglare")
#: Tile side [px] of Q's pruning, and the relative margin of its bound for rounding.
_TILE = 8
_MARGIN = 1e-5
#: Designs per block of the compiled passes.
_BLOCK = 512


def _sparse(weights):
    """Per design the columns with a non-zero weight, in column order, and those weights:
    (D, K) int64 (−1 padded) and (D, K) float64."""
    w = np.asarray(weights, dtype=np.float64)
    nonzero = w != 0
    k = max(1, int(nonzero.sum(axis=1).max()) if w.size else 1)
    order = np.argsort(~nonzero, axis=1, kind="stable")[:, :k]
    present = np.take_along_axis(nonzero, order, axis=1)
    cols = np.where(present, order, -1).astype(np.int64)
    vals = np.where(present, np.take_along_axis(w, order, axis=1), 0.0)
    return cols, vals


@njit(parallel=True, cache=True, error_model="numpy", nogil=True)
def _source_pass(cols, vals, lum, cos_omega, u, threshold, peak, byte_of, shift_of, luminance, packed,
                 e_dir, u_sum):
    """Luminance of the possible source pixels as superpose forms it (float64 sum in column
    order, rounded to float32), E_dir = ΣL·cos σ·ω and ΣL²ω/P² over the sources, and each
    pixel's code (1 source, 3 source and peak) packed two bits a pixel, component by component."""
    n_designs, n_pixels = luminance.shape
    for d in prange(n_designs):
        acc = np.zeros(n_pixels)
        for k in range(cols.shape[1]):
            c = cols[d, k]
            if c < 0:
                continue
            w = vals[d, k]
            for j in range(n_pixels):
                acc[j] += w * np.float64(lum[c, j])
        packed[d, :] = 0
        s_e, s_u = 0.0, 0.0
        for j in range(n_pixels):
            L32 = np.float32(acc[j])
            luminance[d, j] = L32
            L = np.float64(L32)
            if L > threshold:
                code = 3 if L >= peak else 1
                packed[d, byte_of[j]] |= np.uint8(code << shift_of[j])
                s_e += L * cos_omega[j]
                term = L * L * u[j]
                if math.isfinite(term):
                    s_u += term
        e_dir[d] = s_e
        u_sum[d] = s_u


@njit(parallel=True, cache=True, error_model="numpy", nogil=True)
def _group_pass(pattern_of, table_pixel, table_label, table_start, offsets, luminance, omega,
                directions, rows, cols_px, sums):
    """Per design and group slot: Σω, ΣL·ω, ΣL·ω·d̂, ΣL·ω·row, ΣL·ω·col in row-major pixel
    order (as evalglare's grouping does), rows and columns relative to the sources' bounding
    box, whose corner is stored in sums[d, 0, 7:9]. Pattern p of a component has the source
    pixels ``table_pixel`` (in row-major order) with group labels ``table_label`` from
    ``table_start[p]``; the component's groups go to its slots from ``offsets``."""
    n_designs, n_comp = pattern_of.shape
    for d in prange(n_designs):
        r0, c0 = 1 << 60, 1 << 60
        for k in range(n_comp):
            p = pattern_of[d, k]
            for m in range(table_start[p], table_start[p + 1]):
                j = table_pixel[m]
                r0 = min(r0, rows[j])
                c0 = min(c0, cols_px[j])
        for k in range(n_comp):
            p = pattern_of[d, k]
            for m in range(table_start[p], table_start[p + 1]):
                g = offsets[k] + table_label[m] - 1
                j = table_pixel[m]
                L = np.float64(luminance[d, j])
                w = omega[j]
                lw = L * w
                sums[d, g, 0] += w
                sums[d, g, 1] += lw
                for a in range(3):
                    sums[d, g, 2 + a] += lw * directions[j, a]
                sums[d, g, 5] += lw * (rows[j] - r0)
                sums[d, g, 6] += lw * (cols_px[j] - c0)
        sums[d, 0, 7] = r0
        sums[d, 0, 8] = c0


@njit(parallel=True, cache=True, error_model="numpy", nogil=True)
def _q_pass(cols, vals, a, b, wo, tile_start, tile_max, cut, out):
    """Σ w·ω·g over the pixels with g·α ≥ cut; a tile is skipped where its bound
    Σ_c w_c·max_tile g_c (``tile_max``: candidates × tiles) stays below the cut."""
    n_designs = cols.shape[0]
    n_tiles = tile_start.size - 1
    width = 0
    for t in range(n_tiles):
        width = max(width, tile_start[t + 1] - tile_start[t])
    for d in prange(n_designs):
        acc_a = np.zeros(width)
        acc_b = np.zeros(width)
        bound = np.zeros(n_tiles)
        for k in range(cols.shape[1]):
            c = cols[d, k]
            if c >= 0:
                w = vals[d, k]
                for t in range(n_tiles):
                    bound[t] += w * tile_max[c, t]
        total = 0.0
        limit = cut[d] / _ALPHA
        for t in range(n_tiles):
            if bound[t] * (1.0 + _MARGIN) < limit:
                continue
            s, e = tile_start[t], tile_start[t + 1]
            n = e - s
            acc_a[:n] = 0.0
            acc_b[:n] = 0.0
            for k in range(cols.shape[1]):
                c = cols[d, k]
                if c < 0:
                    continue
                w = vals[d, k]
                for j in range(n):
                    acc_a[j] += w * a[c, s + j]
                    acc_b[j] += w * b[c, s + j]
            for j in range(n):
                g = math.sqrt(acc_a[j] * acc_a[j] + acc_b[j] * acc_b[j])
                if g * _ALPHA >= cut[d]:
                    total += wo[s + j] * g
        out[d] = total


class _View:
    """The design-independent parts of one view, from the candidates' maps of it."""

    def __init__(self, name, maps):
        first = maps[0]
        frame = ObserverFrame(tuple(map(float, first.line_of_sight if first.line_of_sight is not None
                                        else (0.0, 0.0, 1.0))), (0.0, -1.0, 0.0))
        geometry = pixel_geometry(first.projection)
        vf = visual_field(first.projection, frame)
        self.name, self.shape, self.frame = name, first.shape, frame
        lum = np.stack([np.asarray(m.luminance, dtype=np.float32) for m in maps])
        finite = np.isfinite(lum)
        if not all(np.array_equal(finite[0], f) for f in finite[1:]):
            raise BadInputError(f"the candidates' maps of view {name!r} differ in their unknown pixels")
        valid = geometry.valid & finite[0] & (vf.cos_sigma >= 0)
        omega = np.where(valid, geometry.solid_angle, 0.0)
        self.directions = geometry.directions
        # Linear field sums per candidate: E_v = ΣL·cos σ·ω.
        flat = np.where(valid, lum, 0.0).reshape(len(maps), -1).astype(np.float64)
        self.e_v = flat @ (vf.cos_sigma * omega).ravel()
        # Possible glare-source pixels: the upper bound over designs exceeds the threshold.
        self.threshold = DEFAULT_SOURCE_THRESHOLD
        self.lum = lum
        self.valid = valid
        self.omega = omega
        self.cos_sigma = vf.cos_sigma
        self.pindex = vf.position_index
        # The position index at each pixel as score_map takes it for a source centred there
        # (NaN: the pixel is invalid or behind the observer — the source's mean direction is
        # used instead).
        sigma, tau = frame.angles(geometry.directions)
        ok = geometry.valid & np.all(np.isfinite(geometry.directions), axis=-1) & (sigma <= math.pi / 2)
        with np.errstate(invalid="ignore"):
            self.p_at = np.where(ok, position_index(sigma, tau), np.nan)
        self._q_setup(maps, valid)

    def bound_sources(self, upper):
        """Fix the possible source pixels from the per-pixel upper bound [cd·m⁻²]."""
        # (a design's luminance is rounded to float32, up to 6e-8 relative above the bound)
        index = np.flatnonzero(self.valid.ravel() & (upper.ravel() > self.threshold * (1.0 - 1e-6)))
        self.src = index
        self.src_lum = np.ascontiguousarray(self.lum.reshape(self.lum.shape[0], -1)[:, index])
        cos_omega = (self.cos_sigma * self.omega).ravel()[index]
        w = self.omega.ravel()[index]
        P = self.pindex.ravel()[index].astype(np.float64)
        with np.errstate(invalid="ignore", divide="ignore"):
            self.src_u = w / (P * P)
        self.src_cos_omega = cos_omega
        self.src_omega = w
        self.src_rows, self.src_cols = np.divmod(index, self.shape[1])
        self.src_dirs = np.ascontiguousarray(self.directions.reshape(-1, 3)[index])
        # Linkage components of all possible source pixels: they never join one another.
        mask = np.zeros(self.shape, bool)
        mask.ravel()[index] = True
        lum = np.full(self.shape, np.nan)
        _, labels = group_sources_evalglare(lum, self.directions, self.omega, mask,
                                            search_angle=DEFAULT_SEARCH_ANGLE, peak_luminance=None)
        comp = labels.ravel()[index] - 1
        count = int(comp.max()) + 1 if comp.size else 0
        self.components = [np.flatnonzero(comp == k) for k in range(count)]
        sizes = np.array([m.size for m in self.components], np.int64)
        comp_start = np.r_[0, np.cumsum(sizes)].astype(np.int64)
        members = np.concatenate(self.components + [np.zeros(0, np.int64)]).astype(np.int64)
        # two bits a pixel, each component from a byte of its own
        self.byte_start = np.r_[0, np.cumsum((2 * sizes + 7) // 8)].astype(np.int64)
        rank = np.empty(index.size, np.int64)
        rank[members] = np.arange(index.size) - np.repeat(comp_start[:-1], sizes)
        self.byte_of = (self.byte_start[:-1][comp] + 2 * rank // 8) if index.size else np.zeros(0, np.int64)
        self.shift_of = (2 * rank % 8).astype(np.int64)
        self.patterns = [dict() for _ in self.components]   # packed codes → pattern id
        self.tables = []                  # per pattern id: its source pixels and their labels
        self.widths = np.zeros(len(self.components), np.int64)  # most groups of a component

    def _q_setup(self, maps, valid):
        """Q's field, evaluated pixels and the tiles of gradient components per candidate."""
        # Q's design-independent parts (blur, evaluated pixels, Σw·ω) from a map with light
        # wherever any candidate has some (a dark probe would stop before them).
        probe = q_Budak2021(np.where(valid, self.lum.sum(axis=0), np.nan), self.directions,
                            self.omega, self.pindex, n_thresholds=_N_THRESHOLDS, size_arcmin=_SIZE_ARCMIN,
                            valid=valid, **_THRESHOLD_OPTIONS)
        settings = probe.settings
        omega32 = self.omega.astype(np.float32)
        field = valid & (omega32 > 0) & ~np.isnan(self.pindex) & \
            np.all(np.isfinite(self.directions), axis=-1)
        self.q_omega = float(np.sum(omega32[field].astype(np.float64)))
        self.q_lw = np.array([float(np.sum((L[field] * omega32[field]).astype(np.float64)))
                              for L in self.lum])
        self.q_weighted = settings.get("weighted_solid_angle_sr", math.nan)
        self.q_ok = self.q_omega > 0 and np.isfinite(probe.contrast).any()
        evaluated = np.isfinite(probe.contrast)
        rows, cols = np.nonzero(evaluated)
        tile = (rows // _TILE) * (self.shape[1] // _TILE + 1) + cols // _TILE
        order = np.lexsort((cols, rows, tile))
        index = (rows * self.shape[1] + cols)[order]
        tile = tile[order]
        starts = np.flatnonzero(np.r_[True, tile[1:] != tile[:-1]]) if tile.size else np.zeros(0, np.int64)
        self.tile_start = np.r_[starts, tile.size].astype(np.int64)
        a = np.empty((len(maps), index.size), np.float32)
        b = np.empty((len(maps), index.size), np.float32)
        for c, L in enumerate(self.lum):
            filled = np.where(field, L, np.float32(0)).astype(np.float32)
            a[c], b[c] = gradient_components(filled, self.directions, index,
                                             sigma_px=settings.get("blur_sigma_px", 0.0))
        self.q_a, self.q_b = a, b
        norm = np.hypot(a.astype(np.float64), b.astype(np.float64))
        # candidates × tiles
        self.q_tile_max = np.ascontiguousarray(np.maximum.reduceat(norm, self.tile_start[:-1], axis=1)
                                               if index.size else np.zeros((len(maps), 0)))
        weight = (np.float32(1.0) / self.pindex.ravel()[index].astype(np.float32)).astype(np.float64)
        self.q_wo = weight * omega32.ravel()[index].astype(np.float64)

    def _pattern(self, k, key, luminance):
        """The pattern id of component ``k`` for its packed codes ``key`` (bytes); a new
        pattern's groups are computed once by the metrics' own grouping."""
        found = self.patterns[k].get(key)
        if found is not None:
            return found
        members = self.components[k]
        pix = self.src[members]
        codes = np.unpackbits(np.frombuffer(key, np.uint8), bitorder="little")[:2 * members.size]
        mask = np.zeros(self.shape, bool)
        mask.ravel()[pix] = codes[0::2].astype(bool)
        lum = np.full(self.shape, np.nan)
        lum.ravel()[pix] = luminance  # of a design with this pattern: its peaks are these
        _, image = group_sources_evalglare(lum, self.directions, self.omega, mask,
                                           search_angle=DEFAULT_SEARCH_ANGLE,
                                           peak_luminance=DEFAULT_PEAK_LUMINANCE)
        labels = image.ravel()[pix].astype(np.int64)
        self.tables.append((members[labels > 0], labels[labels > 0]))
        self.widths[k] = max(self.widths[k], int(labels.max(initial=0)))
        self.patterns[k][key] = len(self.tables) - 1
        return len(self.tables) - 1

    def evaluate(self, cols, vals):
        """Every view metric of a block of designs (sparse weights), as arrays."""
        n = cols.shape[0]
        e_v = (vals * np.where(cols >= 0, self.e_v[np.maximum(cols, 0)], 0.0)).sum(axis=1)
        m = self.src.size
        luminance = np.empty((n, m), np.float32)
        packed = np.empty((n, int(self.byte_start[-1])), np.uint8)
        e_dir = np.empty(n)
        u_sum = np.empty(n)
        _source_pass(cols, vals, self.src_lum, self.src_cos_omega, self.src_u, self.threshold,
                     DEFAULT_PEAK_LUMINANCE, self.byte_of, self.shift_of, luminance, packed, e_dir, u_sum)
        l_b = (e_v - e_dir) / math.pi
        grouped, dgp_sum, n_groups = self._groups(luminance, packed)
        with np.errstate(invalid="ignore", divide="ignore"):
            ugr_pixel = np.where((n_groups > 0) & (l_b > 0) & (u_sum > 0),
                                 8.0 * np.log10(0.25 / l_b * u_sum), np.nan)
        with np.errstate(invalid="ignore", divide="ignore"):
            ugr_grouped = np.where((n_groups > 0) & (l_b > 0) & (grouped > 0),
                                   8.0 * np.log10(0.25 / l_b * grouped), np.nan)
            a1, a2, a3, a4, a5, c1, c2, c3 = _DGP
            dgp = c1 * e_v ** a5 + c3 + np.where(n_groups > 0, c2 * np.log10(1.0 + dgp_sum / e_v ** a3), 0.0)
            dgp = np.where(e_v > 0, np.minimum(dgp, 1.0), np.nan)
        return {"q": self._q(cols, vals), "ugr_pixel": ugr_pixel, "ugr_grouped": ugr_grouped,
                "dgp": dgp, "E_v": e_v, "sources": n_groups}

    def _groups(self, luminance, packed):
        """Grouped-UGR sum ΣL_s²ω_s/P_s², DGP's sum and the number of groups per design."""
        n = packed.shape[0]
        pattern_of = np.empty((n, len(self.components)), np.int64)
        for k in range(len(self.components)):
            part = np.ascontiguousarray(packed[:, self.byte_start[k]:self.byte_start[k + 1]])
            keys, first, inverse = np.unique(part.view(np.dtype((np.void, part.shape[1]))).ravel(),
                                             return_index=True, return_inverse=True)
            members = self.components[k]
            ids = np.array([self._pattern(k, part[f].tobytes(), luminance[f, members]) for f in first])
            pattern_of[:, k] = ids[inverse.ravel()]
        offsets = np.r_[0, np.cumsum(self.widths)].astype(np.int64)
        width = int(offsets[-1])
        if width == 0:
            return np.zeros(n), np.zeros(n), np.zeros(n, np.int64)
        table_pixel = np.concatenate([t[0] for t in self.tables]).astype(np.int64)
        table_label = np.concatenate([t[1] for t in self.tables]).astype(np.int64)
        table_start = np.r_[0, np.cumsum([t[0].size for t in self.tables])].astype(np.int64)
        sums = np.zeros((n, width, 9))
        _group_pass(pattern_of, table_pixel, table_label, table_start, offsets, luminance,
                    self.src_omega, self.src_dirs, self.src_rows, self.src_cols, sums)
        omega, lw = sums[..., 0], sums[..., 1]
        present = omega > 0
        with np.errstate(invalid="ignore", divide="ignore"):
            l_s = lw / omega
            row = sums[..., 5] / lw + sums[:, :1, 7]
            col = sums[..., 6] / lw + sums[:, :1, 8]
        rows, cols = self.shape
        # evalglare's pixel of the mean pixel position (position_pixel_evalglare, vectorised)
        y = np.floor(np.nan_to_num(rows - 1 - row).astype(np.float32).astype(np.float64))
        x = np.floor(np.nan_to_num(col).astype(np.float32).astype(np.float64))
        r = np.clip(rows - 1 - y, 0, rows - 1).astype(np.int64)
        c = np.clip(x, 0, cols - 1).astype(np.int64)
        P = self.p_at[r, c]
        for d, g in zip(*np.nonzero(present & np.isnan(P))):  # centroid pixel off the image
            direction = sums[d, g, 2:5] / np.linalg.norm(sums[d, g, 2:5])
            sigma, tau = self.frame.angles(direction)
            P[d, g] = float(position_index(sigma, tau))
        a1, a2, a3, a4, a5, c1, c2, c3 = _DGP
        with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
            term = l_s * l_s * omega / (P * P)
            grouped = np.where(present & np.isfinite(term), term, 0.0).sum(axis=1)
            dgp_sum = np.where(present, l_s ** a1 * omega ** a2 / P ** a4, 0.0).sum(axis=1)
        return grouped, dgp_sum, present.sum(axis=1)

    def _q(self, cols, vals):
        """Q of each design (NaN where undefined, as q_Budak2021)."""
        n = cols.shape[0]
        if not self.q_ok:
            return np.full(n, np.nan)
        mean = (vals * np.where(cols >= 0, self.q_lw[np.maximum(cols, 0)], 0.0)).sum(axis=1) / self.q_omega
        positive = mean > 0
        delta = np.full(n, np.nan)
        delta[positive] = threshold_luminance_difference(mean[positive], _SIZE_ARCMIN, **_THRESHOLD_OPTIONS)
        cut = _N_THRESHOLDS * delta
        total = np.zeros(n)
        _q_pass(cols, vals, self.q_a, self.q_b, self.q_wo, self.tile_start, self.q_tile_max,
                np.where(positive, cut, np.inf), total)
        with np.errstate(invalid="ignore", divide="ignore"):
            k_th = delta / (mean * _ALPHA)
            q = total / mean / self.q_weighted / k_th
        return np.where(positive & (self.q_weighted > 0), q, np.nan)


class BatchEvaluator:
    """Metrics of many designs at once from candidate solutions (module docstring).

    Parameters
    ----------
    columns : sequence of CandidateSolution
        The candidates at full output, one per column of the weight matrices.
    groups : sequence of sequence of (int, float)
        The mutually exclusive choices: per position, the (column, weight) pairs it can take
        (besides off). The upper bound of a pixel's luminance is the sum over positions of
        the brightest choice — what fixes the possible glare-source pixels.
    base : CandidateSolution, optional
        The space's own luminaires, always on (weight 1).
    """

    def __init__(self, columns, groups, *, base=None):
        if not columns:
            raise BadInputError("a batch evaluator needs at least one candidate")
        # The base first: superpose adds it before the candidates.
        self.columns = ([] if base is None else [base]) + list(columns)
        self.has_base = base is not None
        shift = int(self.has_base)
        self.views = {}
        for name in self.columns[0].maps:
            view = _View(name, [s.maps[name] for s in self.columns])
            upper = view.lum[0].astype(np.float64) if self.has_base else np.zeros(view.shape)
            for choices in groups:
                upper = upper + np.max([np.maximum(w * view.lum[c + shift].astype(np.float64), 0.0)
                                        for c, w in choices] + [np.zeros(view.shape)], axis=0)
            view.bound_sources(upper)
            self.views[name] = view
        self.grids = {g: (np.stack([np.ravel(s.grids[g].illuminance) for s in self.columns]).astype(float),
                          np.array([s.grids[g].average_standard_error for s in self.columns]))
                      for g in self.columns[0].grids}

    def evaluate(self, weights):
        """Metrics of the designs ``weights`` (D × candidates; the base is added at weight 1).

        Returns
        -------
        dict
            ``views[name]`` → {q, ugr_pixel, ugr_grouped, dgp, E_v, sources} arrays (D,), NaN
            where score_map has no value; ``grids[name]`` → {e_m, e_m_standard_error, e_min,
            u0} arrays (D,).
        """
        w = np.atleast_2d(np.asarray(weights, dtype=np.float64))
        if w.shape[1] != len(self.columns) - int(self.has_base) or np.any(~np.isfinite(w)) or np.any(w < 0):
            raise BadInputError(f"weights must be finite, ≥ 0 and of shape (designs, "
                                f"{len(self.columns) - int(self.has_base)})")
        if self.has_base:
            w = np.concatenate([np.ones((w.shape[0], 1)), w], axis=1)
        parts = {name: [] for name in self.views}
        for start in range(0, w.shape[0], _BLOCK):
            cols, vals = _sparse(w[start:start + _BLOCK])
            for name, view in self.views.items():
                parts[name].append(view.evaluate(cols, vals))
        out = {"views": {name: {k: np.concatenate([p[k] for p in blocks]) for k in blocks[0]}
                         for name, blocks in parts.items()}, "grids": {}}
        for name, (E, se) in self.grids.items():
            values = w @ E
            avg = values.mean(axis=1)
            low = values.min(axis=1)
            with np.errstate(invalid="ignore", divide="ignore"):
                u0 = np.where(avg > 0, low / avg, np.nan)
            out["grids"][name] = {"e_m": avg, "e_m_standard_error": np.sqrt((w * w) @ (se * se)),
                                  "e_min": low, "u0": u0}
        return out
