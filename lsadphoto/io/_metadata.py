"""Serialisation of a :class:`~lsadphoto.LuminanceMap`'s metadata (shared by EXR and HDR)."""

import json

import numpy as np

from .._version import __version__
from ..errors import UnsupportedFileError
from ..geometry.base import projection_from_dict

SCHEMA = "lsadphoto.luminance-map/1"


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
    projection = record.get("projection")
    return {
        "projection": None if projection is None else projection_from_dict(projection),
        "line_of_sight": record.get("line_of_sight"),
        "calibration_factor": record.get("calibration_factor", 1.0),
        "calibration_uncertainty": record.get("calibration_uncertainty", 0.0),
        "calibrated": record.get("calibrated", False),
        "provenance": record.get("provenance", {}),
    }
