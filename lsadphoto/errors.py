"""Exceptions and warnings of lsadphoto.

Every error raised on purpose by the package is an :class:`LsadError`; the command line
turns it into a one-line message and the exit code in :attr:`LsadError.exit_code`
(2 for bad input). Warnings have classes of their own so that callers can filter them.
"""

__all__ = [
    "LsadError",
    "BadInputError",
    "MissingMetadataError",
    "OutputError",
    "UnsupportedFileError",
    "LsadWarning",
    "SaturationWarning",
    "MisalignmentWarning",
    "NonUniformSpotWarning",
    "MetadataWarning",
    "SolverWarning",
]


class LsadError(Exception):
    """Base class of the errors lsadphoto raises on purpose."""

    exit_code = 1


class BadInputError(LsadError, ValueError):
    """An input file, value or option cannot be used (exit code 2)."""

    exit_code = 2


class UnsupportedFileError(BadInputError):
    """A file is empty, truncated, corrupt or of a format that cannot be read."""


class MissingMetadataError(BadInputError):
    """Absolute work needs a value (e.g. exposure time) that the file does not carry."""


class OutputError(LsadError, OSError):
    """An output could not be written (disk full, a folder appeared at the target); no
    output of the command was changed. Also an ``OSError``, for callers that catch those."""


class LsadWarning(UserWarning):
    """Base class of lsadphoto's warnings."""


class SaturationWarning(LsadWarning):
    """Part of an image is saturated beyond recovery."""


class MisalignmentWarning(LsadWarning):
    """Frames of an exposure bracket are shifted against each other by more than a pixel."""


class NonUniformSpotWarning(LsadWarning):
    """The image is not uniform inside a spot-meter acceptance cone."""


class MetadataWarning(LsadWarning):
    """Two metadata sources disagree, or a value looks like a placeholder."""


class SolverWarning(LsadWarning):
    """A simulation or view is legal but probably not what was meant (target error not
    reached, an eye on a surface, a view that sees no light)."""
