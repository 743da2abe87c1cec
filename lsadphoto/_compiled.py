"""Compiled kernels: one numba source, compiled ahead of time once per machine, just in time
where that code is missing.

A ``lsadphoto score`` of a 786² picture computes for about 0.1 s; importing numba,
initialising its compiler target and loading the kernels from its cache took 1.4 s of CPU
(docs/performance.md, "Latency of a whole score process"); a further view of a stored
simulation paid 0.8 s of its process for the same. So the package's kernels are
written once, as numba functions decorated with :func:`njit` from this module, and compiled
twice:

* **ahead of time** (``numba.pycc``), all kernels with an ``aot`` signature into one
  extension module, built the first time a kernel is called on a machine (a child process,
  a minute or two; later processes wait for it rather than build twice) into the user's cache
  folder (``$LSADPHOTO_CACHE_DIR``, else ``$XDG_CACHE_HOME/lsadphoto``, else
  ``~/.cache/lsadphoto``), under a key of the kernel sources, the numba, numpy and Python
  versions and the CPU. Loading it takes a millisecond and does not import numba. A call
  runs on one thread (numba's ahead-of-time compiler has no ``parallel``: a ``prange`` is a
  ``range``), with the host CPU's instruction set, each kernel's own error model and, for a
  ``nogil`` kernel, the GIL released, so that callers share large maps out among threads in
  blocks of rows (:func:`run_blocks`, :meth:`Kernel.threads_for`);
* **just in time** (``numba.njit`` with the same options, ``parallel`` included, cached by
  numba) for a call whose arguments match none of the kernel's ``aot`` signatures, where the
  ahead-of-time build failed (no C compiler: the reason is kept in ``build.failed`` in the
  cache folder), and for every call with ``LSADPHOTO_KERNELS=jit``.

The ahead-of-time code runs at every size by default: on the 2 cores measured, numba's
threads did not pay for loading numba even at 24 MP (docs/performance.md); on a machine
with many cores ``LSADPHOTO_KERNELS=jit`` runs the kernels on all of them.

The ahead-of-time functions do not check their arguments (a float32 array where float64 is
compiled would be read as garbage), so each call is matched here against the declared
signatures (dtype, dimensions, C order, alignment, scalar kinds) before it is handed over.
Read-only flags are not compared: the signatures are compiled for writable arrays, and a
kernel writes only to the output arrays its callers allocate (numba's typing, which does
see the flag, refuses a kernel that writes to a read-only input). A kernel's result does
not depend on which compilation ran it: the kernels keep their parallel loops free of
floating-point reductions across iterations, and neither compilation allows fast-math
(tests/test_compiled.py compares the two).

Old builds stay in the cache folder until deleted (about 1 MB each); a failed build is not
retried for the same key until its folder is deleted (e.g. after installing a C compiler).

Kernel modules import :func:`njit`, :data:`prange` and :func:`intrinsic` from here instead of
numba; once numba is needed, :func:`_numba` puts numba's own ``prange`` and intrinsics into
their namespaces, and a :class:`Kernel` presents itself to numba's compiler as its
dispatcher (``_numba_type_``, ``py_func``, ``targetoptions``), so kernels call each other
and inline helpers as plain numba functions do.

References
----------
numba documentation, "Compiling code ahead of time" (``numba.pycc``, pending deprecation
since numba 0.57 with no replacement yet); numba 0.68 sources: ``numba/core/typing/typeof.py``
(an object with a ``_numba_type_`` is typed by it), ``numba/core/untyped_passes.py``
(``InlineInlinables`` reads a callee's ``targetoptions`` and ``py_func``),
``numba/pycc/compiler.py`` (one ``Flags`` for every export, error model "python").
"""

import hashlib
import importlib
import importlib.machinery
import importlib.util
import mmap
import os
import platform
import sys
import threading
from pathlib import Path

import numpy as np

__all__ = ["Kernel", "background", "intrinsic", "njit", "populate", "prange", "row_blocks",
           "run_blocks", "threads"]

#: Modules whose kernels go into the ahead-of-time extension (their sources key the cache).
MODULES = (
    "lsadphoto.io._rgbe",
    "lsadphoto.geometry._kernels",
    "lsadphoto.metrics.field",
    "lsadphoto.metrics.contributions",
    "lsadphoto.metrics.score",
    "lsadphoto.metrics.grouping",
    "lsadphoto.metrics.statistics",
    "lsadphoto.metrics._filters",
    "lsadphoto.metrics.quality",
    "lsadphoto.metrics.grouping_options",
    "lsadphoto.solver.photometry.distribution",
    "lsadphoto.solver.engine",
    "lsadphoto.solver.direct",
    "lsadphoto.solver.cache_grid",
    "lsadphoto.solver.integrators.surface_cache",
    "lsadphoto.solver.integrators.eye",
)
#: Name of the extension module (its ``PyInit_`` symbol).
EXTENSION = "_lsadphoto_kernels"

_KERNELS = []
_STATE = {"numba": None, "library": None, "mode": os.environ.get("LSADPHOTO_KERNELS", "auto")}
_LIBRARY_LOCK = threading.Lock()


def _prange(*args):
    """``range`` until numba compiles the kernel (then numba's ``prange``)."""
    return range(*args)


prange = _prange


class _Intrinsic:
    """An intrinsic's definition, registered with numba when numba is loaded."""

    def __init__(self, definition):
        self.definition = definition


def intrinsic(definition):
    """numba's ``extending.intrinsic``, applied when numba is loaded."""
    if _STATE["numba"] is not None:
        from numba.extending import intrinsic as numba_intrinsic

        return numba_intrinsic(definition)
    return _Intrinsic(definition)


# --- signatures: parsed without numba ---------------------------------------------------------

_SCALARS = {"int64": "int", "float64": "float", "boolean": "bool", "intp": "int"}


def _split_top(text):
    """Split ``text`` at the commas outside brackets and parentheses."""
    parts, depth, start = [], 0, 0
    for i, ch in enumerate(text):
        if ch in "([":
            depth += 1
        elif ch in ")]":
            depth -= 1
        elif ch == "," and depth == 0:
            parts.append(text[start:i].strip())
            start = i + 1
    if text[start:].strip():
        parts.append(text[start:].strip())
    return parts


def _spec(arg):
    """Spec of one argument type of a numba signature string: ``(dtype, ndim, c_order)`` for
    an array, the scalar kind for a scalar, ``("tuple", specs)`` for a ``Tuple((…))``."""
    arg = arg.strip()
    if arg.startswith("Tuple(("):
        return ("tuple", tuple(_spec(a) for a in _split_top(arg[len("Tuple(("):-2])))
    name, _, dims = arg.partition("[")
    name = name.strip()
    if dims:
        axes = _split_top(dims.rstrip("]"))
        dtype = np.dtype("bool" if name == "boolean" else name)
        return (dtype, len(axes), axes[-1].replace(" ", "") == "::1")
    return _SCALARS[name]


def _argument_specs(signature):
    """Per argument of a numba signature string ``"ret(arg, ...)"``: its :func:`_spec`."""
    text = signature.strip()
    depth = 0
    for i in range(len(text) - 1, -1, -1):
        depth += {")": 1, "(": -1}.get(text[i], 0)
        if depth == 0:
            break
    return tuple(_spec(arg) for arg in _split_top(text[i + 1:-1]))


def _matches(specs, args):
    if len(specs) != len(args):
        return False
    for spec, a in zip(specs, args):
        if isinstance(spec, str):
            if isinstance(a, (bool, np.bool_)):
                if spec != "bool":
                    return False
            elif spec == "int":
                if not isinstance(a, (int, np.integer)):
                    return False
            elif spec == "float":
                if not isinstance(a, (float, np.floating)):
                    return False
            else:
                return False
        elif spec[0] == "tuple":
            if not (isinstance(a, tuple) and _matches(spec[1], a)):
                return False
        else:
            dtype, ndim, c_order = spec
            if not (isinstance(a, np.ndarray) and a.dtype == dtype and a.ndim == ndim and
                    a.flags.aligned and (not c_order or a.flags.c_contiguous)):
                return False
    return True


class Kernel:
    """A numba function compiled ahead of time (where an ``aot`` signature matches the
    call) or just in time (numba's dispatcher, made on first need)."""

    def __init__(self, py_func, options, signatures):
        self.py_func = py_func
        self.targetoptions = dict(options)  # read by numba's inliner (``inline``)
        self.signatures = tuple(signatures)
        self._specs = tuple(_argument_specs(s) for s in self.signatures)
        self._compiled = None
        self._dispatcher = None
        self.__name__ = py_func.__name__
        self.__qualname__ = py_func.__qualname__
        self.__module__ = py_func.__module__
        self.__doc__ = py_func.__doc__
        self.__wrapped__ = py_func

    @property
    def export_names(self):
        """Symbols of the ahead-of-time functions, one per signature."""
        tag = self.__module__.removeprefix("lsadphoto.").replace(".", "_")
        return [f"{tag}__{self.__name__}__{k}" for k in range(len(self.signatures))]

    @property
    def dispatcher(self):
        """numba's dispatcher of this kernel (imports numba)."""
        if self._dispatcher is None:
            numba = _numba()
            self._dispatcher = numba.njit(**self.targetoptions)(self.py_func)
        return self._dispatcher

    @property
    def _numba_type_(self):  # numba types a Kernel found in a kernel's globals as its dispatcher
        return self.dispatcher._numba_type_

    def _ahead_of_time(self, args):
        """The ahead-of-time function for ``args``, or None (numba's dispatcher then)."""
        if self._compiled is None:
            library = _library() if self._specs else {}
            self._compiled = [(spec, library[name]) for spec, name in
                              zip(self._specs, self.export_names, strict=True) if name in library]
        for spec, function in self._compiled:
            if _matches(spec, args):
                return function
        return None

    def threads_for(self, *args):
        """Threads among which a caller may share out calls with arguments like ``args``
        (blocks of rows, :func:`run_blocks`): :func:`threads` where the ahead-of-time code
        runs them (one thread each, the GIL released), else 1 — numba's just-in-time code
        runs its parallel loops on its own threads, and its default threading layer refuses
        calls from several Python threads at once."""
        if not self.targetoptions.get("nogil") or self._ahead_of_time(args) is None:
            return 1
        return threads()

    def __call__(self, *args):
        function = self._ahead_of_time(args)
        if function is not None:
            return function(*args)
        return self.dispatcher(*args)


def threads():
    """Threads for the package's kernels: ``LSADPHOTO_THREADS`` where set (a positive
    integer), else the CPUs this process may run on."""
    wanted = os.environ.get("LSADPHOTO_THREADS", "")
    if wanted.isdigit() and int(wanted) > 0:
        return int(wanted)
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return os.cpu_count() or 1


#: Linux's ``MADV_POPULATE_WRITE`` (5.14 and later): fault a range in for writing in one call.
_MADV_POPULATE_WRITE = 23
#: Smaller arrays are left to the page faults (and ctypes unimported).
_POPULATE_MIN_BYTES = 4 << 20
#: Pages faulted in per ``madvise`` call: one call over a few hundred MB of a file mapping
#: whose blocks were reserved (``posix_fallocate``: the geometry cache, lsadphoto.geometry.
#: _map_cache) took 0.7–0.85 s of system time on this project's machine, the same range in
#: 16 MB calls 0.06 s (anonymous memory: the same either way; docs/performance.md, session 16).
_POPULATE_CHUNK_BYTES = 16 << 20
_LIBC = {}


def populate(*arrays):
    """Fault the pages of each contiguous array in for writing, with
    ``madvise(MADV_POPULATE_WRITE)`` (in 16 MB calls), before a kernel writes it: on this project's
    virtual machine that takes about a fifth less system time than faulting fresh memory
    page by page (docs/performance.md, session 10). Called by the thread that then writes
    the block, so that blocks are faulted in on all threads at once. Does nothing to arrays
    under 4 MB, to non-contiguous ones, off Linux or where the kernel refuses the advice
    (before 5.14): their pages fault on first write, as without it. The values are not
    touched."""
    if not sys.platform.startswith("linux"):
        return
    for array in arrays:
        if array.nbytes < _POPULATE_MIN_BYTES or not array.flags.c_contiguous:
            continue
        if "madvise" not in _LIBC:
            import ctypes

            libc = ctypes.CDLL(None, use_errno=True)
            libc.madvise.argtypes = (ctypes.c_void_p, ctypes.c_size_t, ctypes.c_int)
            _LIBC["madvise"] = libc.madvise
        page = mmap.PAGESIZE
        start = -(-array.ctypes.data // page) * page  # whole pages inside the array
        end = (array.ctypes.data + array.nbytes) // page * page
        for a in range(start, end, _POPULATE_CHUNK_BYTES):
            _LIBC["madvise"](a, min(end, a + _POPULATE_CHUNK_BYTES) - a, _MADV_POPULATE_WRITE)


def row_blocks(rows, parts, multiple=1):
    """``rows`` cut into at most ``parts`` blocks ``(r0, r1)`` of about equal size, their
    bounds multiples of ``multiple`` (the last block excepted)."""
    step = -(-rows // max(1, parts))
    step = -(-step // multiple) * multiple
    return [(r0, min(r0 + step, rows)) for r0 in range(0, rows, max(step, 1))]


def run_blocks(task, blocks, workers=None):
    """``task(*block)`` for every block, on up to ``workers`` threads (default
    :func:`threads`), the calling thread one of them; blocks are handed out in order as
    threads come free. Returns the results in the order of ``blocks``; the first exception
    raised by a task is raised here once every thread has finished."""
    blocks = list(blocks)
    workers = min(threads() if workers is None else workers, len(blocks))
    results = [None] * len(blocks)
    if workers <= 1:
        for k, block in enumerate(blocks):
            results[k] = task(*block)
        return results
    import itertools
    import threading

    order = itertools.count()  # next() of a count is atomic under the GIL
    errors = []

    def work():
        for k in order:
            if k >= len(blocks) or errors:
                return
            try:
                results[k] = task(*blocks[k])
            except BaseException as error:  # noqa: BLE001 (re-raised in the caller)
                errors.append(error)
                return

    helpers = [threading.Thread(target=work, daemon=True) for _ in range(workers - 1)]
    for helper in helpers:
        helper.start()
    work()
    for helper in helpers:
        helper.join()
    if errors:
        raise errors[0]
    return results


class _Deferred:
    """A task's result, computed on a thread of its own from the start or in ``result``."""

    def __init__(self, task, concurrent):
        self._task, self._thread, self._outcome = task, None, None
        if concurrent:
            import threading

            self._thread = threading.Thread(target=self._run, daemon=True)
            self._thread.start()

    def _run(self):
        try:
            self._outcome = (True, self._task())
        except BaseException as error:  # noqa: BLE001 (re-raised in ``result``)
            self._outcome = (False, error)

    def result(self):
        """The task's return value (its exception raised here)."""
        if self._thread is None and self._outcome is None:
            self._run()
        elif self._thread is not None:
            self._thread.join()
        done, value = self._outcome
        if not done:
            raise value
        return value


def background(task):
    """``task()`` started on a thread of its own where that can overlap the caller's work —
    more than one thread (:func:`threads`) and the ahead-of-time kernels loaded, which run
    each call on its caller's thread (numba's just-in-time parallel code refuses calls from
    several Python threads at once, ``LSADPHOTO_KERNELS=jit``) — else run by ``result()``
    of the returned object, where the caller would have run it; ``result()`` gives its
    value or raises its exception."""
    return _Deferred(task, threads() > 1 and _STATE["mode"] != "jit" and bool(_library()))


def njit(*, aot=(), **options):
    """Decorator: a :class:`Kernel` with numba ``options`` (``parallel``, ``cache``,
    ``error_model``, ``inline``, …) and ahead-of-time signatures ``aot`` (a numba signature
    string or a tuple of them) for the calls the package makes from Python."""
    signatures = (aot,) if isinstance(aot, str) else tuple(aot)

    def decorate(py_func):
        kernel = Kernel(py_func, options, signatures)
        _KERNELS.append(kernel)
        return kernel

    return decorate


def _numba():
    """Import numba and hand its ``prange`` and intrinsics to the kernel modules."""
    if _STATE["numba"] is None:
        import numba
        from numba.extending import intrinsic as numba_intrinsic

        _STATE["numba"] = numba
        globals()["prange"] = numba.prange
        for name in MODULES:
            module = sys.modules.get(name)
            if module is None:
                continue
            space = vars(module)
            for key, value in list(space.items()):
                if value is _prange:
                    space[key] = numba.prange
                elif isinstance(value, _Intrinsic):
                    space[key] = numba_intrinsic(value.definition)
    return _STATE["numba"]



# --- the ahead-of-time extension --------------------------------------------------------------

def cache_root():
    """The package's cache folder: ``$LSADPHOTO_CACHE_DIR``, else
    ``$XDG_CACHE_HOME/lsadphoto``, else ``~/.cache/lsadphoto`` (the ahead-of-time kernels
    under ``kernels/``, the geometry maps under ``geometry/``)."""
    root = os.environ.get("LSADPHOTO_CACHE_DIR")
    if not root:
        base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
        root = os.path.join(base, "lsadphoto")
    return Path(root)


def cache_folder():
    """Folder of the ahead-of-time extension for these sources, versions and CPU."""
    digest = hashlib.sha256()
    package = Path(__file__).parent  # the sources are read, not imported (nor their packages)
    for name in (*MODULES, __name__):
        digest.update((package / (name.removeprefix("lsadphoto.").replace(".", "/") + ".py")).read_bytes())
    numba_spec = importlib.util.find_spec("numba")
    if numba_spec is None:
        return None
    digest.update(Path(numba_spec.origin).with_name("_version.py").read_bytes())
    digest.update(f"{np.__version__} {sys.version} {platform.machine()}".encode())
    try:
        with open("/proc/cpuinfo", "rb") as info:
            digest.update(next((line for line in info if line.startswith(b"flags")), b""))
    except OSError:
        digest.update(platform.processor().encode())
    return cache_root() / "kernels" / digest.hexdigest()[:24]


def _extension_path(folder):
    return folder / (EXTENSION + importlib.machinery.EXTENSION_SUFFIXES[0])


def _library():
    """name → ahead-of-time function, building the extension first where needed; empty
    when ``LSADPHOTO_KERNELS=jit`` or when it cannot be built. Thread-safe: the first
    kernel calls of a render come from its worker threads at once, and a thread that found
    the library still loading must wait for it, not take it as empty."""
    if _STATE["library"] is None:
        with _LIBRARY_LOCK:
            if _STATE["library"] is None:
                _STATE["library"] = _load_library()
    return _STATE["library"]


def _load_library():
    if _STATE["mode"] == "jit":
        return {}
    try:
        folder = cache_folder()
    except OSError:
        return {}
    if folder is None:
        return {}
    path = _extension_path(folder)
    if not path.exists() and not (folder / "build.failed").exists():
        _build(folder)
    if not path.exists():
        return {}
    spec = importlib.util.spec_from_file_location(EXTENSION, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return {k: v for k, v in vars(module).items() if "__" in k and callable(v)}


def _build(folder):
    """Build the extension into ``folder`` in a child process, one process at a time."""
    try:
        folder.parent.mkdir(parents=True, exist_ok=True)
        lock = open(folder.parent / (folder.name + ".lock"), "w")
    except OSError:
        return
    with lock:
        try:
            import fcntl

            fcntl.flock(lock, fcntl.LOCK_EX)  # another process may be building it
        except ImportError:  # not POSIX: concurrent builds only cost time
            pass
        if _extension_path(folder).exists() or (folder / "build.failed").exists():
            return
        import subprocess

        env = dict(os.environ, LSADPHOTO_KERNELS="jit")
        done = subprocess.run([sys.executable, "-m", __name__, str(folder)], env=env,
                              capture_output=True, text=True)
        if done.returncode != 0 and not _extension_path(folder).exists():
            folder.mkdir(parents=True, exist_ok=True)
            (folder / "build.failed").write_text(done.stdout + done.stderr)


def build_extension(folder):
    """Compile every kernel's ``aot`` signatures into the extension in ``folder`` (run in a
    child process with ``LSADPHOTO_KERNELS=jit``: it imports numba and its ``pycc``)."""
    import json
    import tempfile
    import warnings

    for name in MODULES:
        importlib.import_module(name)
    _numba()
    import llvmlite.binding as llvm
    from numba.core.codegen import AOTCPUCodegen
    from numba.core.errors import NumbaPendingDeprecationWarning

    with warnings.catch_warnings():  # numba.pycc is pending deprecation, with no successor yet
        warnings.simplefilter("ignore", NumbaPendingDeprecationWarning)
        from numba.pycc import CC
        from numba.pycc import compiler as pycc_compiler

    options = {k.py_func: k.targetoptions for k in _KERNELS}
    compile_extra = pycc_compiler.compile_extra

    def compile_with_options(typingctx, targetctx, func, args, return_type, flags, **kwargs):
        # pycc compiles every export with one set of flags (error model "python", the GIL
        # held): give each kernel its own error model and ``nogil``, as its just-in-time
        # compilation has, so that threads can run kernels at the same time (run_blocks).
        flags = flags.copy()
        flags.error_model = options[func].get("error_model", "python")
        flags.release_gil = bool(options[func].get("nogil", False))
        return compile_extra(typingctx, targetctx, func, args, return_type, flags, **kwargs)

    pycc_compiler.compile_extra = compile_with_options
    # The host's instruction set, as numba's JIT uses (pycc's default is the generic CPU).
    AOTCPUCodegen._customize_tm_features = lambda self: llvm.get_host_cpu_features().flatten()
    folder = Path(folder)
    folder.parent.mkdir(parents=True, exist_ok=True)
    staging = Path(tempfile.mkdtemp(prefix=folder.name + ".", dir=folder.parent))
    cc = CC(EXTENSION)
    cc.output_dir = str(staging)
    cc.target_cpu = llvm.get_host_cpu_name()
    manifest = {}
    for kernel in _KERNELS:
        for name, signature in zip(kernel.export_names, kernel.signatures, strict=True):
            cc.export(name, signature)(kernel.py_func)
            manifest[name] = signature
    cc.compile()
    (staging / "manifest.json").write_text(json.dumps(manifest, indent=1))
    try:
        staging.rename(folder)
    except OSError:  # built meanwhile by another process
        import shutil

        shutil.rmtree(staging, ignore_errors=True)


if __name__ == "__main__":  # the kernels register with the imported module, not with __main__
    importlib.import_module("lsadphoto._compiled").build_extension(sys.argv[1])
