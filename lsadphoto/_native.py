"""Native libraries' own messages (LibRaw, OpenEXR), kept off the user's terminal.

C and C++ libraries write to the process's standard output and error (file descriptors 1 and
2) directly, past Python's ``sys.stdout``/``sys.stderr``: a truncated EXR made OpenEXR print
lines before our one-line error, a truncated DNG LibRaw its "Unexpected end of file".
:func:`native_output` redirects both descriptors into a temporary file for the duration of
one library call and hands the lines to the caller, which puts what matters into its own
message.
"""

import contextlib
import io
import os
import sys
import tempfile

__all__ = ["native_output"]


def _fileno(stream):
    try:
        return stream.fileno()
    except (AttributeError, ValueError, OSError):  # e.g. replaced by a capturing object
        return None


@contextlib.contextmanager
def native_output(lines, *, python=False):
    """Capture what is written to file descriptors 1 and 2 inside the block; append its
    non-empty lines to the list ``lines`` on exit (also when the block raises).

    With ``python``, what is written to ``sys.stdout``/``sys.stderr`` is captured too (for
    bindings that report through Python). Otherwise Python's own writes (warnings, progress)
    still reach the terminal: a Python stream on a redirected descriptor is pointed at the
    original for the duration. The redirection is process-wide: other threads' native
    output is captured too.

    Examples
    --------
    >>> import os
    >>> seen = []
    >>> with native_output(seen):
    ...     _ = os.write(2, b"libfoo: chunk 0 is corrupt\\n")
    >>> seen
    ['libfoo: chunk 0 is corrupt']
    """
    names = ("stdout", "stderr")
    streams = {name: getattr(sys, name) for name in names}
    for stream in streams.values():
        with contextlib.suppress(AttributeError, ValueError, OSError):
            stream.flush()
    try:
        saved = {fd: os.dup(fd) for fd in (1, 2)}
    except OSError:  # a detached process without these descriptors: nothing to capture
        yield lines
        return
    captured = io.StringIO()
    replaced = {}
    with tempfile.TemporaryFile() as sink:
        try:
            for fd in (1, 2):
                os.dup2(sink.fileno(), fd)
            for name, stream in streams.items():
                fd = _fileno(stream)
                if python:
                    replaced[name] = captured
                elif fd in saved:
                    replaced[name] = open(saved[fd], "w", encoding=stream.encoding, errors="backslashreplace",
                                          buffering=1, closefd=False)
            for name, stream in replaced.items():
                setattr(sys, name, stream)
            yield lines
        finally:
            for name, stream in replaced.items():
                if stream is not captured:
                    stream.close()
                setattr(sys, name, streams[name])
            for fd, copy in saved.items():
                os.dup2(copy, fd)
                os.close(copy)
            sink.seek(0)
            text = sink.read().decode("utf-8", "replace") + captured.getvalue()
            lines.extend(line.strip() for line in text.splitlines() if line.strip())
