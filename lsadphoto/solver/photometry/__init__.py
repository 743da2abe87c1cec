"""Luminaire photometry: the one intensity-distribution type and the files that give it.

:class:`Photometry` (:mod:`.distribution`) is the luminous intensity distribution of every
non-Lambertian luminaire of the solver — evaluation, exact flux, luminance of the opening,
sampling. It is read from IES LM-63 (1986–2019, :func:`read_ies`) and EULUMDAT
(:func:`read_eulumdat`) files, chosen by suffix with :func:`read_photometry`, or made as an
isotropic point or from a function.

References
----------
ANSI/IES LM-63-19; Stockmar (1990); CIE 121-1996 (C–γ system).
"""

from pathlib import Path

from ...errors import BadInputError
from .distribution import (
    PHOTOMETRY_FORMATS,
    Photometry,
    local_angles,
    luminaire_frame,
    pack_photometries,
    packed_intensity,
)
from .eulumdat import read_eulumdat
from .ies import read_ies

__all__ = ["PHOTOMETRY_FORMATS", "Photometry", "local_angles", "luminaire_frame", "pack_photometries",
           "packed_intensity", "read_eulumdat",
           "read_ies", "read_photometry"]

_READERS = {".ies": read_ies, ".ldt": read_eulumdat}


def read_photometry(path, **kwargs):
    """Read a photometric file, choosing the reader by suffix (``.ies`` or ``.ldt``, any case).

    Parameters
    ----------
    path : path-like
        An IES LM-63 or EULUMDAT file.
    **kwargs
        Keyword options of the reader (``tilt`` for :func:`read_ies`).

    Returns
    -------
    Photometry

    Raises
    ------
    BadInputError
        Unknown suffix (the message lists the known ones), or a missing file.
    UnsupportedFileError
        Malformed file (see the readers).

    References
    ----------
    ANSI/IES LM-63-19; Stockmar (1990).
    """
    suffix = Path(path).suffix.lower()
    if suffix not in _READERS:
        raise BadInputError(f"unknown photometric file suffix {Path(path).suffix!r} of {path}; valid: .ies, .ldt")
    return _READERS[suffix](path, **kwargs)
