"""Progress bars in one place (tqdm on stderr, silent when stderr is not a terminal)."""

import sys

__all__ = ["progress_callback"]


def progress_callback(description, *, enabled=None):
    """A ``progress(done_fraction, eta_s)`` callable drawing a tqdm bar, and its closer.

    Returns ``(callback, close)``; ``callback`` is None when disabled (``enabled`` False, or
    None and stderr is not a terminal), so callers can pass it straight on.
    """
    if enabled is None:
        enabled = sys.stderr.isatty()
    if not enabled:
        return None, lambda: None
    from tqdm import tqdm

    bar = tqdm(total=1000, desc=description, unit="‰", file=sys.stderr, leave=True,
               bar_format="{desc}: {percentage:3.0f}%|{bar}| {postfix}")

    def callback(done_fraction, eta_s):
        bar.n = int(round(1000 * min(max(float(done_fraction), 0.0), 1.0)))
        bar.set_postfix_str(f"about {eta_s:.0f} s left" if eta_s is not None else "", refresh=False)
        bar.refresh()

    return callback, bar.close
