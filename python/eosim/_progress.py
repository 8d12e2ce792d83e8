"""Progress display: tqdm (its notebook widget in Jupyter, text in a terminal) when installed
and stderr is a terminal or a notebook, else plain lines on stderr at every 10 % (no carriage
returns flooding a log file). ``progress=False`` shows nothing; a callable is called as
``callback(done, total)``. One bar per call, with whole counts, kept at the end with its
elapsed time; a sweep of several native runs (``pics(..., vary=...)``) shows one bar for all."""

from __future__ import annotations

import sys
import time
from contextlib import contextmanager


def _interactive() -> bool:
    """A terminal or a Jupyter kernel: where a redrawn bar is readable."""
    if "ipykernel" in sys.modules:
        return True
    try:
        return sys.stderr.isatty()
    except (AttributeError, ValueError):
        return False


class _Lines:
    """Plain progress lines (non-interactive stderr): one at every 10 % and at the end."""

    def __init__(self, desc: str, unit: str):
        self.desc, self.unit, self.t0, self.next = desc, unit, time.monotonic(), 0.0
        self.total = None
        self.done = 0

    def __call__(self, done, total):
        self.total, self.done = total, done
        frac = done / total if total else 1.0
        if frac >= self.next:
            self._line(done, total)
            self.next = (int(frac * 10) + 1) / 10.0

    def _line(self, done, total):
        sys.stderr.write(f"{self.desc}: {done}/{total} {self.unit} ({time.monotonic() - self.t0:.1f} s)\n")
        sys.stderr.flush()

    def close(self):
        if self.total is not None and self.next <= 1.0:
            self._line(self.done, self.total)


class _Bar:
    """A tqdm bar created at the first report (when the total is known)."""

    def __init__(self, tqdm, desc: str, unit: str):
        self.tqdm, self.desc, self.unit, self.bar = tqdm, desc, unit, None

    def __call__(self, done, total):
        if self.bar is None:
            # Whole counts for small totals (no "0.00/6.00"), SI prefixes for large ones.
            self.bar = self.tqdm(total=total, desc=self.desc, unit=self.unit,
                                 unit_scale=total >= 10_000, leave=True)
        self.bar.update(done - self.bar.n)

    def close(self):
        if self.bar is not None:
            self.bar.close()


def _display(desc: str, unit: str):
    if _interactive():
        try:
            from tqdm.auto import tqdm
        except ImportError:  # pragma: no cover - exercised only without tqdm
            tqdm = None
        if tqdm is not None:
            return _Bar(tqdm, desc, unit)
    return _Lines(desc, unit)


@contextmanager
def reporter(progress, desc: str, unit: str):
    """A ``(done, total)`` callable for the native run (or None), closed on exit."""
    if progress is False or progress is None:
        yield None
        return
    if callable(progress) and progress is not True:
        yield progress
        return
    d = _display(desc, unit)
    try:
        yield d
    finally:
        d.close()


@contextmanager
def parts_reporter(progress, desc: str, unit: str, parts: int):
    """For ``parts`` native runs of equal size shown as one: yields ``part(k)``, the
    ``progress`` argument to give run ``k`` (a callable mapping its counts onto the whole)."""
    if progress is False or progress is None:
        yield lambda k: False
        return
    if callable(progress) and progress is not True:
        outer = progress
    else:
        outer = _display(desc, unit)

    def part(k):
        return lambda done, total: outer(k * total + done, parts * total)

    try:
        yield part
    finally:
        if hasattr(outer, "close"):
            outer.close()
