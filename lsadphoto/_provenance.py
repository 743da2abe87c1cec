"""Provenance, built in one place: what made a result, so that it can be traced and repeated.

Every table, map header, store and record carries the same core (STYLE.md habit 13):
``lsadphoto_version``, ``versions`` (the package versions in use), ``timestamp`` (UTC, ISO
8601), and as far as the caller knows them ``arguments``, ``inputs`` (path, size and SHA-256 of
each input file), ``profile`` (camera profile id), ``calibration_factor`` and
``calibration_uncertainty``. Callers add their own keys to the returned dict.

References
----------
Astropy Collaboration, photutils: ``utils/_misc.py::_get_meta`` (versions and date in every
output's metadata), the model for this module.
"""

import datetime
import hashlib
import platform
import sys
from pathlib import Path

from ._version import __version__

__all__ = ["package_versions", "file_record", "timestamp", "build_provenance"]

#: Packages whose versions are recorded when they are loaded (none is imported for it).
RECORDED_PACKAGES = ("numpy", "scipy", "rawpy", "OpenEXR", "cv2", "embreex", "numba", "pyradiance")

#: Files larger than this are recorded by size and modification time only [bytes]. SHA-256
#: took 0.45 s per 25 MiB on the project's shared 2-core machine under load, so hashing each
#: frame of a RAW bracket (20–80 MB apiece) would add seconds to a map that takes a few;
#: profiles, tables, scenes and small maps stay well below the limit and are hashed.
HASH_LIMIT = 16 << 20


def package_versions():
    """Versions of Python, lsadphoto and the recorded packages that are loaded.

    Returns
    -------
    dict of str → str
    """
    versions = {"python": platform.python_version(), "lsadphoto": __version__}
    for name in RECORDED_PACKAGES:
        module = sys.modules.get(name)
        version = getattr(module, "__version__", None) if module is not None else None
        if version is not None:
            versions[name] = str(version)
    return versions


def file_record(path, *, hash=True):
    """``{"path", "size_bytes", "modified", "sha256"}`` of an input file.

    ``modified`` is the modification time (UTC, ISO 8601); ``sha256`` is None where the file
    is larger than :data:`HASH_LIMIT`, cannot be read, or ``hash`` is false; ``size_bytes``
    and ``modified`` are None where the file does not exist.

    Examples
    --------
    >>> import tempfile, os
    >>> fd, name = tempfile.mkstemp(); os.write(fd, b"abc"); os.close(fd)
    3
    >>> r = file_record(name); r["size_bytes"], r["sha256"][:16]
    (3, 'ba7816bf8f01cfea')
    """
    path = Path(path)
    try:
        stat = path.stat()
    except OSError:
        return {"path": str(path), "size_bytes": None, "modified": None, "sha256": None}
    size = stat.st_size
    modified = datetime.datetime.fromtimestamp(stat.st_mtime, datetime.UTC).isoformat(timespec="seconds")
    digest = None
    if hash and size <= HASH_LIMIT:
        sha = hashlib.sha256()
        try:
            with open(path, "rb") as fh:
                for block in iter(lambda: fh.read(1 << 20), b""):
                    sha.update(block)
            digest = sha.hexdigest()
        except OSError:
            digest = None
    return {"path": str(path), "size_bytes": size, "modified": modified, "sha256": digest}


def timestamp():
    """The current time, UTC, ISO 8601 to the second (e.g. ``2026-12-01T17:40:00+00:00``)."""
    return datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds")


def build_provenance(*, arguments=None, inputs=None, profile=None, calibration_factor=None,
                     calibration_uncertainty=None, hash_inputs=True):
    """The provenance core of a result; callers add their own keys.

    Parameters
    ----------
    arguments : dict, optional
        The options the result was computed with.
    inputs : iterable of path-like, optional
        Input files; each becomes a :func:`file_record`.
    profile : str, optional
        Camera profile id.
    calibration_factor, calibration_uncertainty : float, optional
        Absolute calibration factor [cd·m⁻² per relative unit] and its relative standard
        uncertainty [1].
    hash_inputs : bool
        Hash the inputs (False where a caller has hashed them already).

    Returns
    -------
    dict
    """
    record = {"lsadphoto_version": __version__, "versions": package_versions(), "timestamp": timestamp()}
    if arguments is not None:
        record["arguments"] = dict(arguments)
    if inputs is not None:
        record["inputs"] = [file_record(p, hash=hash_inputs) for p in inputs]
    if profile is not None:
        record["profile"] = profile
    if calibration_factor is not None:
        record["calibration_factor"] = calibration_factor
    if calibration_uncertainty is not None:
        record["calibration_uncertainty"] = calibration_uncertainty
    return record
