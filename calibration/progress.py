"""Progress of long work, on stderr: one-line step messages and counted bars with a time
estimate (tqdm).

Library functions take ``progress``: None (silent) or a callable taking a message. The
command line passes a :class:`Progress`, which can also draw bars; a long loop asks
:func:`counter` for one and updates it the same way whether or not it is drawn, so a
plain callable (``print``, a test's list.append) still gets the messages.
"""
from __future__ import annotations

import sys

from tqdm import tqdm


class Progress:
    """Messages and bars on ``stream`` (default: stderr at the time of each call)."""

    def __init__(self, stream=None):
        self._stream = stream

    @property
    def stream(self):
        return sys.stderr if self._stream is None else self._stream

    def __call__(self, message: str) -> None:
        tqdm.write(str(message), file=self.stream)  # above any bar being drawn, not through it

    def bar(self, total: int | None, desc: str, unit: str = "it") -> tqdm:
        return tqdm(total=total, desc=desc, unit=unit, file=self.stream, dynamic_ncols=True, mininterval=0.5,
                    smoothing=0.1)


def counter(progress, total: int | None, desc: str, unit: str = "it") -> tqdm:
    """A bar of ``total`` steps (``unit``) labelled ``desc`` when ``progress`` draws bars;
    otherwise a silent one (and ``desc`` passed to ``progress`` as a message, if given):
    ``update``, ``set_postfix_str`` and ``close`` work on both."""
    draw = getattr(progress, "bar", None)
    if draw is not None:
        return draw(total, desc, unit)
    if progress is not None:
        progress(desc)
    return tqdm(total=total, disable=True)
