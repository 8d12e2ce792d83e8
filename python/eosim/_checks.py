"""Arguments checked in Python, so that a wrong one raises ``TypeError``/``ValueError`` naming
it (not an ``OverflowError`` from the conversion to an unsigned integer), and a missing input
file ``FileNotFoundError``."""

from __future__ import annotations

import numbers
import os
from typing import Optional

from . import _native


class InputFileNotFoundError(FileNotFoundError, _native.ConfigError):
    """An input file (experiment, region, site, acquisitions) that does not exist. Both a
    ``FileNotFoundError`` and an :class:`eosim.ConfigError`."""


def count(name: str, value, *, minimum: int = 1) -> Optional[int]:
    """``value`` as an ``int`` of at least ``minimum`` (``None`` passes), else ``TypeError`` or
    ``ValueError`` naming ``name``."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise TypeError(f"{name} must be an integer, not {type(value).__name__} ({value!r})")
    if value < minimum:
        raise ValueError(f"{name} = {value}: must be an integer of at least {minimum}")
    return int(value)


def flag(name: str, value) -> bool:
    """``value`` if it is a ``bool``, else ``TypeError`` naming ``name``."""
    if not isinstance(value, bool):
        raise TypeError(f"{name} must be True or False, not {value!r}")
    return value


def existing(path, what: str) -> str:
    """``path`` (str or path-like) if the file exists, else :class:`InputFileNotFoundError`."""
    if not isinstance(path, (str, os.PathLike)):
        raise TypeError(f"{what} must be a path, a TOML string or a dict, not {type(path).__name__}")
    p = os.fspath(path)
    if not os.path.exists(p):
        import errno

        raise InputFileNotFoundError(errno.ENOENT, f"{what} not found", p)
    return p
