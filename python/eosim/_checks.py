"""Arguments checked in Python, so that a wrong one raises ``TypeError``/``ValueError`` naming
it (not an ``OverflowError`` from the conversion to an unsigned integer), and a missing input
file ``FileNotFoundError``."""

from __future__ import annotations

import numbers
import os
from typing import Optional

from . import _native


class InputFileNotFoundError(FileNotFoundError, _native.ConfigError):
    """Raised when an input file given to a function does not exist.

    The file may be an experiment, a region, a site, an acquisitions CSV or a bundle folder
    passed by path. Both a ``FileNotFoundError`` (``errno`` is ``ENOENT``, ``filename`` the
    path as given) and an :class:`eosim.ConfigError`, so either ``except`` clause catches it.
    Files named inside an experiment (a phase table, a profile) are reported by a
    ``ConfigError`` naming their key instead.

    See Also
    --------
    ConfigError : Every invalid input.

    Examples
    --------
    >>> import eosim
    >>> try:
    ...     eosim.load("no_such_experiment.toml")
    ... except eosim.InputFileNotFoundError as e:
    ...     print(e.filename, isinstance(e, FileNotFoundError), isinstance(e, eosim.ConfigError))
    no_such_experiment.toml True True
    """


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


def existing(path, what: str, accepted: str = "a path") -> str:
    """``path`` (str or path-like) if the file exists, else :class:`InputFileNotFoundError`;
    ``TypeError`` saying what the argument may be (``accepted``) for anything else."""
    if not isinstance(path, (str, os.PathLike)):
        raise TypeError(f"{what} must be {accepted}, not {type(path).__name__}")
    p = os.fspath(path)
    if not os.path.exists(p):
        import errno

        raise InputFileNotFoundError(errno.ENOENT, f"{what} not found", p)
    return p
