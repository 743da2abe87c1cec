"""The one checker of TOML inputs against a declared schema (profiles, scenes, manifests, …).

A schema is a tree of :class:`Table` (a TOML table with declared keys), :class:`Key` (one
value: its type, whether it is required, its default, range and choices), :class:`ArrayOf`
(an array of tables, e.g. ``[[luminaire]]``), :class:`MapOf` (a table of named entries, e.g.
``[materials.wall]``) and :class:`Variants` (a table whose keys depend on a discriminator
such as ``model = "opencv-fisheye"``). :func:`validate` checks a parsed
document against it and returns a copy with the defaults filled in; :func:`read_toml` reads a
file and validates it. Every problem is a :class:`~lsadphoto.errors.BadInputError` with one
line naming the file, the table and the key — and, for an unknown key, the closest valid name
— so a misspelled ``[vignettng]`` section is an error, never silence.

Examples
--------
>>> schema = Table({"id": Key(str, required=True),
...                 "sensor": Table({"width_mm": Key(float, minimum=0, exclusive=True)})})
>>> validate({"id": "cam", "sensor": {"width_mm": 23.5}}, schema, source="p.toml")
{'id': 'cam', 'sensor': {'width_mm': 23.5}}
>>> validate({"id": "cam", "sensr": {}}, schema, source="p.toml")
Traceback (most recent call last):
...
lsadphoto.errors.BadInputError: p.toml: unknown key 'sensr' (did you mean 'sensor'?); valid: id, sensor
"""

import difflib
import math
import tomllib

from ._validation import check_file
from .errors import BadInputError

__all__ = ["Key", "Table", "ArrayOf", "MapOf", "Variants", "validate", "read_toml"]

_MISSING = object()
_TYPE_NAMES = {str: "a string", int: "an integer", float: "a number", bool: "true or false",
               list: "an array", dict: "a table"}


class Key:
    """One value of a table.

    Parameters
    ----------
    kind : type
        ``str``, ``int``, ``float`` (integers are accepted and converted), ``bool`` or ``list``.
    required : bool
        The key must be present.
    default : object
        Value filled in when the key is absent (not for required keys).
    choices : sequence, optional
        The valid values; an error lists them.
    minimum, maximum : float, optional
        Range of a number, or of every element of a list of numbers.
    exclusive : bool
        The range's ends are excluded (``minimum=0, exclusive=True``: positive).
    items : type or Key, optional
        For ``kind=list``: the type of every element (``float`` or ``int`` or ``str``), or a
        :class:`Key` that checks every element (e.g. the rows of a matrix).
    length : int, tuple of int or range, optional
        For ``kind=list``: the allowed number(s) of elements.
    doc : str
        What the value means, with its unit (used in messages and docs).
    """

    def __init__(self, kind, *, required=False, default=_MISSING, choices=None, minimum=None,
                 maximum=None, exclusive=False, items=None, length=None, doc=""):
        self.kind, self.required, self.default = kind, required, default
        self.choices, self.minimum, self.maximum, self.exclusive = choices, minimum, maximum, exclusive
        self.items, self.length, self.doc = items, length, doc

    def check(self, value, where):
        value = _scalar(value, self.kind, where)
        if self.kind is list:
            value = self._check_list(value, where)
        elif self.kind in (int, float):
            self._check_range(value, where)
        if self.choices is not None and value not in self.choices:
            valid = ", ".join(repr(c) for c in self.choices)
            raise BadInputError(f"{where} must be one of {valid}, got {value!r}")
        return value

    def _check_list(self, value, where):
        lengths = (self.length,) if isinstance(self.length, int) else self.length
        if lengths is not None and len(value) not in lengths:
            if isinstance(lengths, range):
                allowed = f"{lengths.start} to {lengths.stop - 1}"
            else:
                allowed = " or ".join(str(n) for n in lengths)
            raise BadInputError(f"{where} must have {allowed} elements, got {len(value)}")
        if self.items is None:
            return list(value)
        if isinstance(self.items, Key):
            return [self.items.check(v, f"{where}[{i}]") for i, v in enumerate(value)]
        out = [_scalar(v, self.items, f"{where}[{i}]") for i, v in enumerate(value)]
        if self.items in (int, float):
            for i, v in enumerate(out):
                self._check_range(v, f"{where}[{i}]")
        return out

    def _check_range(self, value, where):
        low, high = self.minimum, self.maximum
        if low is not None and (value < low or (self.exclusive and value == low)):
            raise BadInputError(f"{where} must be {'>' if self.exclusive else '≥'} {low}, got {value!r}")
        if high is not None and (value > high or (self.exclusive and value == high)):
            raise BadInputError(f"{where} must be {'<' if self.exclusive else '≤'} {high}, got {value!r}")


class Table:
    """A TOML table with declared keys; unknown keys are errors unless ``open``.

    ``open=True`` is for free-form tables (``[provenance]``: any keys, string values).
    """

    def __init__(self, keys=None, *, required=False, open=False, doc=""):
        self.keys, self.required, self.open, self.doc = dict(keys or {}), required, open, doc

    def check(self, value, where):
        if not isinstance(value, dict):
            raise BadInputError(f"{where or 'document'} must be a table, got {_describe(value)}")
        unknown = [k for k in value if k not in self.keys]
        if unknown and not self.open:
            key = unknown[0]
            close = difflib.get_close_matches(key, list(self.keys), n=1, cutoff=0.6)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            valid = ", ".join(self.keys) or "none"
            raise BadInputError(f"{_where(where)}unknown key {key!r}{hint}; valid: {valid}")
        out = {k: v for k, v in value.items() if k not in self.keys}
        for name, spec in self.keys.items():
            path = f"{where}.{name}" if where else name
            if name in value:
                out[name] = spec.check(value[name], path)
            elif getattr(spec, "required", False):
                raise BadInputError(f"{_where(where)}missing required key {name!r}")
            elif isinstance(spec, Key) and spec.default is not _MISSING:
                out[name] = spec.default
        return out


class ArrayOf:
    """An array of tables (``[[name]]``), each checked against ``table``."""

    def __init__(self, table, *, required=False, min_items=0, doc=""):
        self.table, self.required, self.min_items, self.doc = table, required, min_items, doc

    def check(self, value, where):
        if not isinstance(value, list) or not all(isinstance(v, dict) for v in value):
            raise BadInputError(f"{where} must be an array of tables ([[{where}]]), got {_describe(value)}")
        if len(value) < self.min_items:
            raise BadInputError(f"{where} needs at least {self.min_items} entries, got {len(value)}")
        return [self.table.check(v, f"{where}[{i}]") for i, v in enumerate(value)]


class MapOf:
    """A table whose keys are names chosen by the user (``[materials.wall]``,
    ``[materials.floor]``), each value checked against ``table``."""

    def __init__(self, table, *, required=False, doc=""):
        self.table, self.required, self.doc = table, required, doc

    def check(self, value, where):
        if not isinstance(value, dict):
            raise BadInputError(f"{where} must be a table of named entries, got {_describe(value)}")
        return {name: self.table.check(v, f"{where}.{name}") for name, v in value.items()}


class Variants:
    """A table whose valid keys depend on a discriminator key, e.g. a lens model's name.

    ``variants`` maps each value of ``key`` to the :class:`Table` of the other keys;
    ``default`` is the variant used when ``key`` is absent.
    """

    def __init__(self, key, variants, *, default=None, required=False, doc=""):
        self.key, self.variants, self.default, self.required, self.doc = key, variants, default, required, doc

    def check(self, value, where):
        if not isinstance(value, dict):
            raise BadInputError(f"{where} must be a table, got {_describe(value)}")
        name = value.get(self.key, self.default)
        if not isinstance(name, str) or name not in self.variants:  # a table or list is unhashable
            valid = ", ".join(repr(v) for v in self.variants)
            raise BadInputError(f"{where}.{self.key} must be one of {valid}, got {name!r}")
        table = self.variants[name]
        rest = table.check({k: v for k, v in value.items() if k != self.key}, where)
        return {self.key: name, **rest}


def validate(data, schema, *, source):
    """Check ``data`` (a parsed TOML document) against ``schema``; return it with defaults.

    Parameters
    ----------
    data : dict
        The document, as :func:`tomllib.loads` returns it.
    schema : Table
        The declared schema of the whole document.
    source : str
        What to name in messages (usually the file's path).

    Raises
    ------
    BadInputError
        One line: ``SOURCE: KEY.PATH problem``.
    """
    try:
        return schema.check(data, "")
    except BadInputError as exc:
        raise BadInputError(f"{source}: {exc}") from None


def read_toml(path, schema, *, what="TOML file"):
    """Read the TOML file ``path`` and :func:`validate` it; ``what`` names it in messages.

    References
    ----------
    TOML v1.0.0, https://toml.io/en/v1.0.0.
    """
    path = check_file(path, what)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except UnicodeDecodeError:
        raise BadInputError(f"{path}: {what} is not UTF-8 text") from None
    except tomllib.TOMLDecodeError as exc:
        raise BadInputError(f"{path}: not a valid TOML {what} ({exc})") from None
    return validate(data, schema, source=str(path))


def _scalar(value, kind, where):
    if kind is float and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    ok = isinstance(value, kind) and not (kind in (int, float) and isinstance(value, bool))
    if not ok:
        raise BadInputError(f"{where} must be {_TYPE_NAMES.get(kind, kind.__name__)}, got {_describe(value)}")
    if kind is float and not math.isfinite(value):
        raise BadInputError(f"{where} must be finite, got {value!r}")
    return value


def _describe(value):
    if isinstance(value, dict):
        return "a table"
    if isinstance(value, list):
        return "an array"
    return repr(value)


def _where(where):
    return f"[{where}] " if where else ""
