"""EULUMDAT (``.ldt``) photometric files, read without third parties.

References
----------
Stockmar, A. W. (1990), "EULUMDAT – ein Leuchtendatenformat für den europäischen
Beleuchtungsplaner", Tagungsband Licht '90, 641–644 (the de-facto EULUMDAT specification).
DIAL/Lighting Analysts (2009), "Handling of absolute photometry data in EULUMDAT files"
(negative number of lamps).
"""

import math
from pathlib import Path

import numpy as np

from ...errors import UnsupportedFileError
from ._reading import Tokens, check_angles, expand, guarded, read_text
from .distribution import Photometry

__all__ = ["read_eulumdat"]

_LDT_SYMMETRY = {0: "none", 1: "rotational", 2: "plane C0-C180", 3: "plane C90-C270", 4: "quadrant"}

#: Header lines 1–25 (Stockmar 1990): (key, kind); kind "s" text, "i" integer, "f" number.
_LDT_HEADER = (
    ("company", "s"), ("type_indicator", "i"), ("symmetry_indicator", "i"), ("n_c_planes", "i"),
    ("c_plane_distance", "f"), ("n_intensities", "i"), ("gamma_distance", "f"),
    ("report_number", "s"), ("luminaire_name", "s"), ("luminaire_number", "s"), ("file_name", "s"),
    ("date_user", "s"), ("luminaire_length", "f"), ("luminaire_width", "f"), ("luminaire_height", "f"),
    ("luminous_length", "f"), ("luminous_width", "f"), ("luminous_height_c0", "f"),
    ("luminous_height_c90", "f"), ("luminous_height_c180", "f"), ("luminous_height_c270", "f"),
    ("downward_flux_fraction", "f"), ("light_output_ratio", "f"), ("conversion_factor", "f"),
    ("measurement_tilt", "f"),
)
_LAMP_FIELDS = (("n_lamps", "i"), ("lamp_type", "s"), ("lamp_flux", "f"), ("colour", "s"),
                ("colour_rendering", "s"), ("wattage", "f"))


def _ldt_stored_planes(isym, mc, name):
    """0-based indices into the C-angle list of the planes stored for a symmetry (Mc1..Mc2)."""
    if isym == 0:
        return list(range(mc))
    if isym == 1:
        return [0]
    if isym == 2:
        if mc % 2:
            raise UnsupportedFileError(f"{name}: Isym 2 needs an even number of C-planes, got Mc = {mc}")
        return list(range(mc // 2 + 1))
    if mc % 4:
        raise UnsupportedFileError(f"{name}: Isym {isym} needs Mc divisible by 4, got Mc = {mc}")
    if isym == 3:
        # Stockmar: Mc1 = 3·Mc/4 + 1, Mc2 = Mc1 + Mc/2 (1-based) — C270 through C0 to C90.
        return [(3 * mc // 4 + k) % mc for k in range(mc // 2 + 1)]
    return list(range(mc // 4 + 1))


@guarded
def read_eulumdat(path):
    """Read a EULUMDAT (``.ldt``) photometric file into a :class:`Photometry`.

    Header lines 1–25 and the lamp sets (line 26: number of sets n, then six lines per set:
    number of lamps, type, total lamp flux [lm], colour, colour rendering, wattage [W]) are
    read line by line; the direct ratios (10 values), the Mc C-angles, the Ng γ-angles and
    the intensities [cd/klm] are read as a token stream. The stored C-planes follow the
    symmetry indicator Isym (Stockmar 1990): 0 all Mc planes; 1 one plane (rotational);
    2 C0…C180; 3 C270…C360/C0…C90 (Mc1 = 3Mc/4+1, Mc2 = Mc1+Mc/2); 4 C0…C90.

    Absolute intensity [cd] = value [cd/klm] × Φ_lamps/1000 × conversion factor (line 24),
    with Φ_lamps the *total* lamp flux of the first lamp set (line 26c, already the total of
    all its lamps). A negative number of lamps marks absolute photometry (DIAL/Lighting
    Analysts 2009): line 26c is then the luminaire flux, LORL is 100 %, and the conversion
    is the same; ``metadata["absolute"]`` records it.

    Parameters
    ----------
    path : path-like
        The ``.ldt`` file.

    Returns
    -------
    Photometry
        Opening [m]: length = luminous length (line 16), width = luminous width (line 17),
        height = mean of the four luminous heights (lines 18–21); a width of 0 (circular)
        becomes ``width = length = −diameter`` (the IES convention). ``metadata`` holds the
        header fields by name, ``"lamp_sets"``, ``"direct_ratios"`` and ``"absolute"``.

    Raises
    ------
    UnsupportedFileError
        Malformed, truncated or inconsistent file (Isym outside 0–4, counts, non-numbers).

    References
    ----------
    Stockmar, A. W. (1990), EULUMDAT (the de-facto specification, as tabulated by
    Lighting Analysts' "EULUMDAT file format"); DIAL/Lighting Analysts (2009), absolute
    photometry in EULUMDAT; CIE 121-1996 (C–γ system).
    """
    path = Path(path)
    name = str(path)
    lines = [line.rstrip("\r") for line in read_text(path).split("\n")]
    metadata = {}
    cursor = 0

    def take(key, kind):
        nonlocal cursor
        if cursor >= len(lines):
            raise UnsupportedFileError(f"{name}: truncated, header line {cursor + 1} ({key}) missing")
        text = lines[cursor].strip()
        cursor += 1
        if kind == "s":
            return text
        try:
            value = float(text.replace(",", ".")) if text else math.nan
        except ValueError:
            raise UnsupportedFileError(
                f"{name}: line {cursor} ({key}) is not a number: {text[:20]!r}") from None
        if kind == "i":
            if not math.isfinite(value) or value != int(value):
                raise UnsupportedFileError(f"{name}: line {cursor} ({key}) must be an integer, got {text[:20]!r}")
            return int(value)
        if not math.isfinite(value):
            raise UnsupportedFileError(f"{name}: line {cursor} ({key}) is empty or not finite")
        return value

    for key, kind in _LDT_HEADER:
        metadata[key] = take(key, kind)
    isym, mc, ng = metadata["symmetry_indicator"], metadata["n_c_planes"], metadata["n_intensities"]
    if isym not in _LDT_SYMMETRY:
        raise UnsupportedFileError(f"{name}: symmetry indicator Isym = {isym} is not 0–4")
    if mc < 1 or ng < 2:
        raise UnsupportedFileError(f"{name}: Mc = {mc} C-planes and Ng = {ng} intensities per plane are too few")
    n_sets = take("number of lamp sets", "i")
    if n_sets < 1:
        raise UnsupportedFileError(f"{name}: number of lamp sets must be at least 1, got {n_sets}")
    sets = []
    for index in range(n_sets):
        sets.append({key: take(f"lamp set {index + 1} {key}", kind) for key, kind in _LAMP_FIELDS})
    metadata["lamp_sets"] = sets

    tokens = Tokens("\n".join(lines[cursor:]), name, decimal_comma=True)
    metadata["direct_ratios"] = tokens.numbers(10, "direct ratio").tolist()
    c_list = tokens.numbers(mc, "C angle")
    gamma = tokens.numbers(ng, "gamma angle")
    stored = _ldt_stored_planes(isym, mc, name)
    values = tokens.numbers(len(stored) * ng, "intensity").reshape(len(stored), ng)
    leftover = tokens.rest()
    if leftover:
        raise UnsupportedFileError(
            f"{name}: {len(leftover)} values after the {len(stored)}×{ng} intensity table "
            f"(wrong Mc, Ng or Isym?), first {leftover[0][:20]!r}")
    check_angles(c_list, "C angles", name, 0.0, 360.0)
    check_angles(gamma, "gamma angles", name, 0.0, 180.0)
    if np.any(values < 0):
        raise UnsupportedFileError(f"{name}: negative intensities")

    lamp = sets[0]
    if not lamp["lamp_flux"] > 0:
        raise UnsupportedFileError(f"{name}: lamp flux {lamp['lamp_flux']:g} lm of lamp set 1 must be positive")
    scale = lamp["lamp_flux"] / 1000.0 * metadata["conversion_factor"]
    if not scale > 0:
        raise UnsupportedFileError(f"{name}: conversion factor {metadata['conversion_factor']:g} must be positive")
    symmetry = _LDT_SYMMETRY[isym]
    c_angles, candela = expand(c_list[stored], values * scale, symmetry, name)

    metadata.update(symmetry=symmetry, absolute=lamp["n_lamps"] < 0, lamp_flux=lamp["lamp_flux"],
                    stored_c_angles=c_list[stored].tolist(), c_angles_listed=c_list.tolist())
    length = metadata["luminous_length"] / 1000.0
    width = metadata["luminous_width"] / 1000.0
    heights = [metadata[f"luminous_height_c{c}"] for c in (0, 90, 180, 270)]
    height = float(np.mean(heights)) / 1000.0
    if width == 0 and length > 0:  # circular luminous area: diameter in line 16
        width = length = -length
    return Photometry(c_angles=c_angles, gamma_angles=gamma, candela=candela,
                      width=width, length=length, height=height,
                      source=name, format="EULUMDAT", metadata=metadata)
