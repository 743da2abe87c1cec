"""A camera's geometry and visual-field maps kept on disk between processes.

A survey scores hundreds of photos from one camera, and every ``lsadphoto score`` process
of a 24-megapixel fisheye used to compute the same maps again: the solid angle, validity,
position index and cos σ of every pixel (0.3 s of CPU and 408 MB of fresh memory, which
this project's virtual machine faults in slowly: docs/performance.md, session 16). These
maps depend only on the camera model, the picture size, the observer frame, the position
index method and the code; :func:`cached_geometry_and_field` keeps them in one file per
such key and maps it read-only into later processes, which then read the maps straight
from the page cache.

Correctness:

* **The key** is the exact JSON of everything that determines the maps — the projection's
  :meth:`to_dict`, the picture size, the frame's three axes (floats written exactly), the
  position index method, the package version, a hash of the Python sources that set up
  the kernels' arguments (:data:`SOURCES`), the ahead-of-time extension's key (the kernel
  sources, numba, numpy, Python, the CPU: :func:`lsadphoto._compiled.cache_folder`) and
  which compilation runs the kernel. The file name is a hash of the key; the file's header
  holds the key itself, and a file whose key differs is not used.
* **A file is used only if it is whole**: magic, format, key, layout and size must match,
  and a checksum of sampled pages of every map (one page in every 256 and each map's last
  page) must agree; otherwise it is ignored and rebuilt (and replaced). The sample catches a
  file written only in part; it is not a check of every bit.
* **Writing is atomic** through the package's one writer (:func:`lsadphoto._atomic.
  atomic_path`): the maps are computed straight into a temporary file beside the target
  (mapped shared: no copy) and renamed into place once whole, so no process ever sees a
  file in part. Blocks are reserved first (``posix_fallocate``), so that a full disk is an
  ``OSError`` here (the maps are then computed in memory, as without the cache), not a
  fault while the kernel writes.
* **A crash cannot leave a file that looks whole.** Flushing 408 MB to disk (``fsync``)
  cost a process 0.9 s of system time here (docs/performance.md, session 16), more than
  the cache saves, so the writing process does not flush: the header records the kernel's
  boot id (``/proc/sys/kernel/random/boot_id``), and a file is used if it was written
  since the last boot (the page cache then holds exactly what was written, flushed or
  not) or if it is *sealed*: flushed and marked so (one header byte, flushed too). A
  process that reads an unsealed file older than :data:`SEAL_AFTER_SECONDS` (by then the
  kernel has written it back by itself, so the flush is cheap) seals it on a daemon thread
  that does not hold up the end of the process. An unsealed file from an earlier boot —
  the machine went down before it was flushed — is ignored and rebuilt. Where there is no
  boot id (off Linux) a file is flushed and sealed before it is renamed into place.
* **Any failure falls back** to computing the maps in memory: an unwritable folder, a full
  disk, a corrupt file. The cache never changes a result: a map read from it is the map
  the same code computes, bit for bit (tests/test_geometry_map_cache.py).

Settings: ``LSADPHOTO_GEOMETRY_CACHE`` = ``off`` (or ``0``, ``no``, ``false``) disables
it; a folder path moves it (default ``geometry/`` in :func:`lsadphoto._compiled.
cache_root`). ``LSADPHOTO_GEOMETRY_CACHE_MB`` bounds the folder's size (default
:data:`DEFAULT_BUDGET_MB`): after each write the least recently used files beyond it are
deleted. Only pictures above :data:`MIN_PIXELS` are cached (below it the maps cost a few
hundredths of a second), and only on POSIX systems (file mappings with ``mmap``'s ``prot``).
"""

import contextlib
import hashlib
import json
import math
import mmap
import os
import sys
import threading
import time
import zlib
from pathlib import Path

import numpy as np

__all__ = ["DEFAULT_BUDGET_MB", "MIN_PIXELS", "SOURCES", "cache_directory",
           "cached_geometry_and_field"]

#: File format version (part of the key and of the header).
FORMAT = 1
MAGIC = b"LSADGEO\x00"
#: Bytes before the first map (the header: magic, length, JSON); maps start on page bounds.
_HEADER_BYTES = 1 << 16
_ALIGN = 1 << 12
#: Default size bound of the cache folder [MB]: four 24-megapixel entries (408 MB each).
DEFAULT_BUDGET_MB = 2048
#: Pictures of more pixels than this are cached (the combined geometry and field pass of
#: :func:`lsadphoto.geometry.field.visual_field`).
MIN_PIXELS = 1 << 20
#: Python sources, beside the kernels, whose code sets the maps (their bytes key the cache).
SOURCES = ("field.py", "fisheye.py", "opencv.py", "position_index.py", "observer.py",
           "_map_cache.py")
#: (name, dtype) of the maps, in file order.
MAPS = (("solid_angle", np.float64), ("position_index", np.float32),
        ("cos_sigma", np.float32), ("valid", np.bool_))
#: Sampled checksum: one page in this many, and each map's last page.
_SAMPLE_EVERY_PAGES = 256
#: An unsealed file of this boot is flushed and sealed by a reader once it is this old [s]:
#: Linux writes dirty pages back after 30 s (``vm.dirty_expire_centisecs``) and wakes its
#: flusher every 5 s.
SEAL_AFTER_SECONDS = 60.0
#: Temporary files older than this [s] are left-overs of killed processes (deleted).
_STALE_SECONDS = 3600.0
_OFF = {"0", "off", "no", "false"}
_SOURCES_DIGEST = []
#: The file mappings and reads used here (``mmap``'s ``prot``, ``os.pread``) are POSIX's:
#: elsewhere the maps are computed in memory.
_POSIX = hasattr(mmap, "PROT_READ") and hasattr(os, "pread") and hasattr(os, "pwrite")
_EXTENSION_KEY = []


def cache_directory():
    """The cache folder, or None where ``LSADPHOTO_GEOMETRY_CACHE`` disables it."""
    setting = os.environ.get("LSADPHOTO_GEOMETRY_CACHE", "").strip()
    if setting.lower() in _OFF:
        return None
    if setting:
        return Path(setting)
    from .._compiled import cache_root

    return cache_root() / "geometry"


def _budget_bytes():
    text = os.environ.get("LSADPHOTO_GEOMETRY_CACHE_MB", "")
    try:
        megabytes = float(text) if text.strip() else DEFAULT_BUDGET_MB
    except ValueError:
        megabytes = DEFAULT_BUDGET_MB
    return max(0.0, megabytes) * (1 << 20)


def _sources_digest():
    if not _SOURCES_DIGEST:
        digest = hashlib.sha256()
        here = Path(__file__).parent
        for name in SOURCES:
            digest.update(name.encode() + b"\0" + (here / name).read_bytes())
        _SOURCES_DIGEST.append(digest.hexdigest())
    return _SOURCES_DIGEST[0]


def _kernels_key():
    """The ahead-of-time extension's key and which compilation runs the kernels."""
    from .. import _compiled

    library = _compiled._library()
    if not _EXTENSION_KEY:  # the hash of the kernel sources, once per process (6 ms)
        folder = _compiled.cache_folder()
        _EXTENSION_KEY.append(None if folder is None else folder.name)
    return {"extension": _EXTENSION_KEY[0], "compiled": "ahead-of-time" if library else "jit"}


def key_text(projection_key, shape, axes, method):
    """The exact text of the cache key (see the module docstring)."""
    from .._version import __version__

    return json.dumps({
        "format": FORMAT, "version": __version__, "sources": _sources_digest(),
        "kernels": _kernels_key(), "numpy": np.__version__, "byteorder": sys.byteorder,
        "projection": json.loads(projection_key), "shape": [int(n) for n in shape],
        "axes": [[float(x) for x in np.asarray(a).reshape(-1)] for a in axes],
        "method": method,
    }, sort_keys=True)


def _layout(shape):
    """{name: (offset, dtype)} and the file size for maps of ``shape``."""
    n = math.prod(shape)
    offset, layout = _HEADER_BYTES, {}
    for name, dtype in MAPS:
        layout[name] = (offset, np.dtype(dtype))
        offset += -(-n * np.dtype(dtype).itemsize // _ALIGN) * _ALIGN
    return layout, offset


def _checksum(buffer, layout, n):
    """CRC-32 of sampled pages of every map (see the module docstring)."""
    crc = 0
    view = memoryview(buffer)
    page = _ALIGN
    for _, (offset, dtype) in sorted(layout.items()):
        size = n * dtype.itemsize
        starts = list(range(0, size, page * _SAMPLE_EVERY_PAGES))
        starts.append(max(0, size - page))
        for start in starts:
            crc = zlib.crc32(view[offset + start:offset + min(size, start + page)], crc)
    view.release()
    return crc


def _arrays(buffer, layout, shape):
    n = math.prod(shape)
    return {name: np.frombuffer(buffer, dtype=dtype, count=n, offset=offset).reshape(shape)
            for name, (offset, dtype) in layout.items()}


#: Header: magic (8 bytes), JSON length (8, little-endian), the seal byte, then the JSON.
_SEAL_AT = 16
_JSON_AT = 24


def _boot_id():
    """The running kernel's boot id (Linux), else None."""
    try:
        with open("/proc/sys/kernel/random/boot_id", "rb") as f:
            return f.read().strip().decode("ascii") or None
    except (OSError, UnicodeDecodeError):
        return None


def _seal(path):
    """Flush the file ``path`` to disk, then mark it sealed and flush that byte."""
    try:
        fd = os.open(path, os.O_RDWR)
    except OSError:
        return
    try:
        os.fsync(fd)
        os.pwrite(fd, b"\x01", _SEAL_AT)
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _seal_on_thread(path):
    """:func:`_seal` on a daemon thread: it does not hold up the end of the process (a
    process that ends first leaves the file unsealed, valid until the next boot)."""
    thread = threading.Thread(target=_seal, args=(path,), name="lsadphoto-geometry-seal",
                              daemon=True)
    thread.start()
    _SEALING.append(thread)


#: Threads flushing and sealing cache files (:func:`wait_for_seals`; tests).
_SEALING = []


def wait_for_seals():
    """Wait until the cache files this process started flushing are sealed."""
    while _SEALING:
        _SEALING.pop().join()


def _load(path, key, shape):
    """The maps of the file ``path`` (read-only, mapped), or None where it is missing or
    not a whole file of this key."""
    layout, size = _layout(shape)
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return None
    try:
        if os.fstat(fd).st_size != size:
            return None
        head = os.pread(fd, _HEADER_BYTES, 0)
        if head[:8] != MAGIC:
            return None
        length = int.from_bytes(head[8:16], "little")
        if not 0 < length <= _HEADER_BYTES - _JSON_AT:
            return None
        header = json.loads(head[_JSON_AT:_JSON_AT + length].decode("utf-8"))
        if header.get("key") != key or header.get("size") != size:
            return None
        sealed = head[_SEAL_AT] == 1
        boot = header.get("boot_id")
        if not sealed and (boot is None or boot != _boot_id()):
            return None  # written before the last boot and never flushed: maybe in part
        written = header.get("written")
        if not isinstance(written, (int, float)):
            return None
        buffer = mmap.mmap(fd, size, prot=mmap.PROT_READ)
    except (OSError, ValueError, UnicodeDecodeError):
        return None
    finally:
        os.close(fd)
    if header.get("checksum") != _checksum(buffer, layout, math.prod(shape)):
        return None
    with contextlib.suppress(OSError):
        os.utime(path)  # least recently used first out
    if not sealed and time.time() - written > SEAL_AFTER_SECONDS:
        _seal_on_thread(path)
    return _arrays(buffer, layout, shape)


class _PendingWrite:
    """A temporary file holding the maps, flushed and renamed into place on a thread."""

    def __init__(self, path, key, shape):
        from .._atomic import atomic_path

        self.path, self.key, self.shape = path, key, shape
        self.layout, self.size = _layout(shape)
        path.parent.mkdir(parents=True, exist_ok=True)
        self._context = atomic_path(path)
        temp = self._context.__enter__()
        try:
            fd = os.open(temp, os.O_RDWR)
            try:
                os.ftruncate(fd, self.size)
                if hasattr(os, "posix_fallocate"):
                    os.posix_fallocate(fd, 0, self.size)  # ENOSPC here, not a fault later
                self.buffer = mmap.mmap(fd, self.size, prot=mmap.PROT_READ | mmap.PROT_WRITE)
            finally:
                os.close(fd)
        except BaseException:
            self._context.__exit__(*sys.exc_info())
            raise
        self.temp = temp
        self.arrays = _arrays(self.buffer, self.layout, shape)

    def finish(self):
        """Header and rename into place, unflushed (see the module docstring); where there
        is no boot id, flushed and sealed before the rename."""
        boot = _boot_id()
        header = json.dumps({"key": self.key, "size": self.size, "boot_id": boot,
                             "written": time.time(),
                             "checksum": _checksum(self.buffer, self.layout,
                                                   math.prod(self.shape))}).encode("utf-8")
        if len(header) > _HEADER_BYTES - _JSON_AT:
            self.abandon()
            return
        self.buffer[:_JSON_AT + len(header)] = (MAGIC + len(header).to_bytes(8, "little")
                                                + bytes(_JSON_AT - _SEAL_AT) + header)
        if boot is None:
            _seal(self.temp)
        try:
            self._context.__exit__(None, None, None)
        except Exception:  # noqa: BLE001 (OutputError: the maps are simply not cached)
            return
        _evict(self.path.parent, keep=self.path)

    def abandon(self):
        """Delete the temporary file (the maps stay mapped for this process)."""
        with contextlib.suppress(BaseException):
            self._context.__exit__(OSError, OSError("not cached"), None)


def _evict(folder, *, keep):
    """Delete the least recently used cache files beyond the size budget, and temporary
    files of killed processes."""
    budget = _budget_bytes()
    now = time.time()
    entries = []
    with contextlib.suppress(OSError):
        for entry in os.scandir(folder):
            with contextlib.suppress(OSError):
                stat = entry.stat()
                if entry.name.startswith("."):  # the atomic writer's temporary files
                    if ".tmp" in entry.name and now - stat.st_mtime > _STALE_SECONDS:
                        os.unlink(entry.path)
                elif entry.name.endswith(".maps"):
                    entries.append((stat.st_mtime, stat.st_size, entry.path))
    total = sum(size for _, size, _ in entries)
    for _, size, path in sorted(entries):
        if total <= budget:
            break
        if Path(path) == keep:
            continue
        with contextlib.suppress(OSError):
            os.unlink(path)
            total -= size


def cached_geometry_and_field(projection_key, shape, axes, method, compute):
    """The maps of ``compute(allocate)`` — a function that computes the solid angle,
    validity, position index and cos σ maps of a picture of ``shape`` into arrays it gets
    from ``allocate(name, shape, dtype)`` (:data:`MAPS`'s names), and called without
    ``allocate`` into arrays of its own in memory — from the cache file of
    this key where there is a whole one, else computed into a new cache file; computed in
    memory where the cache is off, the picture small or the file cannot be written.
    Returns what ``compute`` returns."""
    folder = cache_directory()
    if folder is None or math.prod(shape) <= MIN_PIXELS or not _POSIX:
        return compute()
    try:
        key = key_text(projection_key, shape, axes, method)
    except (OSError, ValueError):
        return compute()
    path = folder / (hashlib.sha256(key.encode("utf-8")).hexdigest()[:32] + ".maps")
    maps = _load(path, key, shape)
    if maps is not None:
        return compute(lambda name, shape_, dtype: _stored(maps, name, shape_, dtype),
                       stored=True)
    from ..errors import LsadError

    try:
        pending = _PendingWrite(path, key, shape)
    except (OSError, LsadError):
        return compute()
    try:
        result = compute(lambda name, shape_, dtype: _stored(pending.arrays, name, shape_,
                                                             dtype))
    except BaseException:
        pending.abandon()
        raise
    pending.finish()
    return result


def _stored(maps, name, shape, dtype):
    array = maps[name]
    if array.shape != tuple(shape) or array.dtype != np.dtype(dtype):
        raise ValueError(f"cache map {name}: {array.shape} {array.dtype}, wanted {shape} {dtype}")
    return array
