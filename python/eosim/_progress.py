"""Progress display: tqdm (its notebook widget in Jupyter, text in a terminal) when installed,
else a one-line text counter on stderr. ``progress=False`` shows nothing; a callable is called
as ``callback(done, total)``."""

from __future__ import annotations

import sys
from contextlib import contextmanager


@contextmanager
def reporter(progress, desc: str, unit: str):
    """A ``(done, total)`` callable for the native run (or None), closed on exit."""
    if progress is False or progress is None:
        yield None
        return
    if callable(progress) and progress is not True:
        yield progress
        return
    try:
        from tqdm.auto import tqdm
    except ImportError:  # pragma: no cover - exercised only without tqdm
        tqdm = None
    if tqdm is not None:
        bar = None

        def cb(done, total):
            nonlocal bar
            if bar is None:
                bar = tqdm(total=total, desc=desc, unit=unit, unit_scale=True, leave=False)
            bar.update(done - bar.n)

        try:
            yield cb
        finally:
            if bar is not None:
                bar.close()
        return

    def text(done, total):
        pct = 100.0 * done / total if total else 100.0
        sys.stderr.write(f"\r{desc}: {pct:5.1f} % ({done}/{total} {unit})")
        sys.stderr.flush()

    try:
        yield text
    finally:
        sys.stderr.write("\n")
