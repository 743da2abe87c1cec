"""Serialisation of a :class:`~lsadphoto.LuminanceMap`'s metadata (shared by EXR and HDR)."""

import json

import numpy as np

from .._schema import Key, Table, validate
from .._version import __version__
from ..errors import BadInputError, UnsupportedFileError
from ..geometry.base import projection_from_dict

SCHEMA = "lsadphoto.luminance-map/1"

#: What :func:`metadata_json` writes (null values are left out before the check). Open: keys
#: that a later version adds are kept, not refused.
METADATA_SCHEMA = Table({
    "schema": Key(str, required=True, choices=(SCHEMA,)),
    "lsadphoto_version": Key(str),
    "unit": Key(str, choices=("cd/m2",)),
    "projection": Key(dict),
    "line_of_sight": Key(list, items=float, length=3),
    "calibration_factor": Key(float, default=1.0, minimum=0, exclusive=True),
    "calibration_uncertainty": Key(float, default=0.0, minimum=0),
    "calibrated": Key(bool, default=False),
    "provenance": Key(dict),
}, open=True)


def _default(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"cannot serialise {type(value).__name__}")


def metadata_json(lmap):
    """JSON text holding everything of ``lmap`` except its pixel arrays."""
    record = {
        "schema": SCHEMA,
        "lsadphoto_version": __version__,
        "unit": "cd/m2",
        "projection": None if lmap.projection is None else lmap.projection.to_dict(),
        "line_of_sight": None if lmap.line_of_sight is None else list(lmap.line_of_sight),
        "calibration_factor": lmap.calibration_factor,
        "calibration_uncertainty": lmap.calibration_uncertainty,
        "calibrated": lmap.calibrated,
        "provenance": lmap.provenance,
    }
    return json.dumps(record, default=_default, separators=(",", ":"))


def metadata_fields(text, path):
    """Keyword arguments for :class:`LuminanceMap` from :func:`metadata_json` text."""
    try:
        record = json.loads(text)
    except json.JSONDecodeError as exc:
        raise UnsupportedFileError(f"{path}: corrupt lsadphoto metadata ({exc.msg})") from None
    if not isinstance(record, dict) or record.get("schema") != SCHEMA:
        raise UnsupportedFileError(f"{path}: unknown lsadphoto metadata schema")
    try:
        record = validate({k: v for k, v in record.items() if v is not None}, METADATA_SCHEMA,
                          source="lsadphoto metadata")
        projection = record.get("projection")
        projection = None if projection is None else projection_from_dict(projection)
    except (BadInputError, TypeError, ValueError) as exc:
        raise UnsupportedFileError(f"{path}: corrupt lsadphoto metadata ({exc})") from None
    return {
        "projection": projection,
        "line_of_sight": record.get("line_of_sight"),
        "calibration_factor": record["calibration_factor"],
        "calibration_uncertainty": record["calibration_uncertainty"],
        "calibrated": record["calibrated"],
        "provenance": record.get("provenance", {}),
    }
