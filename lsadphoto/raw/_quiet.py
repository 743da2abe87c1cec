"""Third-party parsers' log records about corrupt files, kept off the user's terminal.

tifffile and exifread log every malformed tag of a damaged file (dozens of lines on stderr
through logging's last-resort handler when the application configures no logging);
lsadphoto reports a file's problem once, as one error or warning of its own.
"""

import contextlib
import logging


@contextlib.contextmanager
def quiet_loggers(*names):
    """Silence the loggers ``names`` inside the block; their levels are restored after it."""
    loggers = [logging.getLogger(name) for name in names]
    levels = [logger.level for logger in loggers]
    for logger in loggers:
        logger.setLevel(logging.CRITICAL + 1)
    try:
        yield
    finally:
        for logger, level in zip(loggers, levels, strict=True):
            logger.setLevel(level)
