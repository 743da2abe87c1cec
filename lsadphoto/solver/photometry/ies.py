"""IES LM-63 photometric files (1986–2019), read without third parties.

References
----------
ANSI/IES LM-63-19, *Approved Method: IES Standard File Format for the Electronic Transfer
of Photometric Data and Related Information* (2019). ANSI/IESNA LM-63-02 (2002).
IESNA LM-63-95 (1995).
"""

import re
from pathlib import Path

import numpy as np

from ..._validation import check_array
from ...errors import UnsupportedFileError
from ._reading import Tokens, check_angles, expand, guarded, read_text
from .distribution import ANGLE_EPS, Photometry

__all__ = ["read_ies"]

_FOOT = 0.3048  # [m], international foot (LM-63 units type 1)


_IES_VERSIONS = {
    "IESNA:LM-63-1995": "IES LM-63-1995",
    "IESNA:LM-63-2002": "IES LM-63-2002",
    "IES:LM-63-2019": "IES LM-63-2019",
    "IESNA:LM-63-2019": "IES LM-63-2019",
    "IESNA91": "IES LM-63-1991",
    "IESNA95": "IES LM-63-1995",  # not a standard first line, but written by old tools (Radiance examp1)
}

_PHOTOMETRIC_TYPES = {1: "C", 2: "B", 3: "A"}


def _ies_tilt(tokens, name):
    """The TILT block: lamp-to-luminaire geometry, angles [deg] and multiplying factors."""
    geometry = tokens.integer("TILT lamp-to-luminaire geometry")
    count = tokens.integer("number of TILT angles", minimum=1)
    angles = tokens.numbers(count, "TILT angle")
    factors = tokens.numbers(count, "TILT multiplying factor")
    if count > 1 and np.any(np.diff(angles) <= 0):
        raise UnsupportedFileError(f"{name}: TILT angles are not strictly ascending")
    return {"geometry": geometry, "angles": angles.tolist(), "factors": factors.tolist()}


@guarded
def read_ies(path, *, tilt=0.0):
    """Read an IES LM-63 photometric file (type C photometry) into a :class:`Photometry`.

    Accepts LM-63-1986 (no version line), -1991 (``IESNA91``), -1995 (``IESNA:LM-63-1995``,
    also the non-standard ``IESNA95``), -2002 (``IESNA:LM-63-2002``) and -2019
    (``IES:LM-63-2019``) files: keyword lines (``[MORE]`` continues the previous keyword),
    numeric blocks spread over any number of lines, space or comma delimiters, and every
    horizontal-angle symmetry of LM-63 (single 0° = rotational; 0–90° = quadrant; 0–180° =
    bilateral about the 0–180° plane; 90–270° = bilateral about the 90–270° plane; 0–360°
    = none).

    The intensities [cd] are the file's values × candela multiplier × ballast factor × (1995
    and earlier only) ballast-lamp photometric factor × TILT factor. The lamp count and
    lumens per lamp do not scale them: LM-63 candela values already refer to the rated lamps
    (lumens per lamp = −1 marks absolute photometry). The second value of line 11 is the
    ballast-lamp factor in 1995, "future use" in 2002 and the file generation type in 2019;
    only the first is applied.

    Parameters
    ----------
    path : path-like
        The ``.ies`` file.
    tilt : float, keyword-only
        Installed tilt of the luminaire [deg] at which a TILT=INCLUDE or TILT=<file> table
        is evaluated (linear interpolation, clamped to the table), in the sense of the
        table's lamp-to-luminaire geometry code (recorded, not interpreted). Ignored for
        TILT=NONE.

    Returns
    -------
    Photometry
        ``metadata`` holds the keywords (``"TEST"``, ``"MANUFAC"``, …), ``"header_lines"``
        (other header text), ``"tilt"`` and the numeric header (``"n_lamps"``,
        ``"lumens_per_lamp"``, ``"multiplier"``, ``"ballast_factor"``, …, ``"absolute"``).

    Raises
    ------
    UnsupportedFileError
        Malformed or truncated file, photometric type A or B, a horizontal-angle range
        that matches no LM-63 symmetry, a missing TILT file.
    BadInputError
        The file does not exist.

    References
    ----------
    ANSI/IES LM-63-19 (file structure, TILT, luminous opening, symmetry); ANSI/IESNA
    LM-63-02 (§3 definitions; file structure); IESNA LM-63-95; CIE 121-1996 (C–γ system).

    Examples
    --------
    >>> import tempfile
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = Path(folder) / "isotropic.ies"
    ...     _ = path.write_text("IES:LM-63-2019\\n[TEST] doctest\\nTILT=NONE\\n"
    ...                         "1 -1 1 3 1 1 2 0 0 0\\n1 1 10\\n0 45 90\\n0\\n100 100 100\\n")
    ...     p = read_ies(path)
    >>> p.format, round(p.luminous_flux, 3)   # 2π·100 lm over the lower hemisphere
    ('IES LM-63-2019', 628.319)
    """
    tilt = float(check_array(tilt, "tilt", ndim=0, finite=True, dtype=float))
    path = Path(path)
    name = str(path)
    lines = read_text(path).splitlines()
    first = lines[0].strip()
    version_line = first.upper().replace(" ", "")
    fmt = _IES_VERSIONS.get(version_line)
    header_start = 1
    if fmt is None:
        if version_line.startswith(("IESNA", "IES:")):
            raise UnsupportedFileError(f"{name}: unknown IES version line {first[:40]!r}")
        fmt, header_start = "IES LM-63-1986", 0
    tilt_index = next((k for k, line in enumerate(lines) if re.match(r"\s*TILT\s*=", line, re.IGNORECASE)), None)
    if tilt_index is None:
        raise UnsupportedFileError(f"{name}: no TILT= line (not an IES LM-63 file, or truncated)")

    metadata = {"version_line": first, "header_lines": []}
    keywords = {}
    last = None
    for line in lines[header_start:tilt_index]:
        text = line.strip()
        match = re.match(r"\[([^\]]+)\]\s*(.*)$", text)
        if match:
            key, value = match.group(1).strip().upper(), match.group(2).strip()
            if key == "MORE" and last is not None:
                keywords[last] = f"{keywords[last]}\n{value}"
                continue
            keywords[key] = f"{keywords[key]}\n{value}" if key in keywords else value
            last = key
        elif text:
            metadata["header_lines"].append(text)
    metadata.update(keywords)

    tilt_line = lines[tilt_index].strip()
    tilt_value = tilt_line.split("=", 1)[1].strip() if "=" in tilt_line else ""
    tokens = Tokens("\n".join(lines[tilt_index + 1:]), name)
    if tilt_value.upper() == "NONE":
        tilt_table = None
    elif tilt_value.upper() == "INCLUDE":
        tilt_table = _ies_tilt(tokens, name)
    elif tilt_value:
        tilt_path = path.parent / tilt_value
        if not tilt_path.is_file():
            raise UnsupportedFileError(f"{name}: TILT file {tilt_value!r} not found beside the IES file")
        tilt_table = _ies_tilt(Tokens(read_text(tilt_path), str(tilt_path)), str(tilt_path))
    else:
        raise UnsupportedFileError(f"{name}: malformed TILT line {tilt_line[:40]!r}")
    tilt_factor = 1.0
    if tilt_table is not None:
        tilt_factor = float(np.interp(float(tilt), tilt_table["angles"], tilt_table["factors"]))
        tilt_table.update(source=tilt_value, applied_tilt=float(tilt), applied_factor=tilt_factor)
    metadata["tilt"] = tilt_table

    n_lamps = tokens.integer("number of lamps")
    lumens = tokens.number("lumens per lamp")
    multiplier = tokens.number("candela multiplier")
    n_vertical = tokens.integer("number of vertical angles", minimum=1)
    n_horizontal = tokens.integer("number of horizontal angles", minimum=1)
    photometric_type = tokens.integer("photometric type")
    units_type = tokens.integer("units type")
    width, length, height = (tokens.number(what) for what in ("width", "length", "height"))
    ballast_factor = tokens.number("ballast factor")
    second_factor = tokens.number("ballast-lamp photometric factor / future use / file generation type")
    input_watts = tokens.number("input watts")

    if photometric_type not in _PHOTOMETRIC_TYPES:
        raise UnsupportedFileError(f"{name}: photometric type {photometric_type} is not 1 (C), 2 (B) or 3 (A)")
    if photometric_type != 1:
        raise UnsupportedFileError(
            f"{name}: photometric type {_PHOTOMETRIC_TYPES[photometric_type]} is not supported (type C only)")
    if units_type not in (1, 2):
        raise UnsupportedFileError(f"{name}: units type {units_type} is not 1 (feet) or 2 (metres)")
    if n_vertical < 2:
        raise UnsupportedFileError(f"{name}: at least two vertical angles are needed, got {n_vertical}")

    gamma = tokens.numbers(n_vertical, "vertical angle")
    c_stored = tokens.numbers(n_horizontal, "horizontal angle")
    values = tokens.numbers(n_vertical * n_horizontal, "candela value").reshape(n_horizontal, n_vertical)
    leftover = tokens.rest()
    if leftover:
        raise UnsupportedFileError(
            f"{name}: {len(leftover)} values after the {n_horizontal}×{n_vertical} candela table "
            f"(wrong counts in the header?), first {leftover[0][:20]!r}")
    check_angles(gamma, "vertical angles", name, 0.0, 180.0)
    if n_horizontal > 1:
        check_angles(c_stored, "horizontal angles", name, 0.0, 360.0)
    if np.any(values < 0):
        raise UnsupportedFileError(f"{name}: negative candela values")

    first_c, last_c = c_stored[0], c_stored[-1]
    if n_horizontal == 1:
        symmetry = "rotational"
    elif first_c == 0 and last_c == 90:
        symmetry = "quadrant"
    elif first_c == 0 and last_c == 180:
        symmetry = "plane C0-C180"
    elif first_c == 90 and last_c == 270:
        symmetry = "plane C90-C270"
    elif first_c == 0 and last_c > 180 and 360 - last_c <= np.diff(c_stored).max() + ANGLE_EPS:
        symmetry = "none"  # LM-63 ends at 360; a last angle one step short closes periodically
    else:
        raise UnsupportedFileError(
            f"{name}: horizontal angles {first_c:g}..{last_c:g} match no LM-63 symmetry "
            "(0, 0–90, 0–180, 90–270, 0–360)")

    scale = multiplier * ballast_factor * tilt_factor
    if fmt in ("IES LM-63-1986", "IES LM-63-1991", "IES LM-63-1995"):
        scale *= second_factor
    if not scale > 0:
        raise UnsupportedFileError(
            f"{name}: candela multiplier × ballast factor(s) × TILT factor = {scale:g} is not positive")
    c_angles, candela = expand(c_stored, values * scale, symmetry, name)
    to_metre = _FOOT if units_type == 1 else 1.0

    metadata.update(
        n_lamps=n_lamps, lumens_per_lamp=lumens, absolute=(lumens == -1), multiplier=multiplier,
        photometric_type="C", units_type=units_type, ballast_factor=ballast_factor,
        input_watts=input_watts, symmetry=symmetry, stored_c_angles=c_stored.tolist(),
        rated_lamp_lumens=(n_lamps * lumens if lumens > 0 else None),
    )
    if fmt == "IES LM-63-2019":
        metadata["file_generation_type"] = second_factor
    elif fmt == "IES LM-63-2002":
        metadata["future_use"] = second_factor
    else:
        metadata["ballast_lamp_photometric_factor"] = second_factor

    return Photometry(c_angles=c_angles, gamma_angles=gamma, candela=candela,
                      width=width * to_metre, length=length * to_metre, height=height * to_metre,
                      source=name, format=fmt, metadata=metadata)
