"""Inputs given as a path, a TOML string or a dict, turned into (TOML text, path named in
errors and anchoring relative paths)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Mapping, Union

from . import _native

Source = Union[str, os.PathLike, Mapping[str, Any]]


def toml_source(source: Source, base_dir: str | os.PathLike | None = None) -> tuple[str, Path]:
    """TOML text and its path. A ``dict`` is written as TOML (named ``<dict>``), a string holding
    a newline or ``=`` is TOML text (named ``<string>``), anything else is a file path.
    ``base_dir``: the folder relative paths of a dict or string are taken from (default: the
    current folder)."""
    base = Path(base_dir) if base_dir is not None else Path()
    if isinstance(source, Mapping):
        return _native.dict_to_toml(dict(source)), base / "<dict>"
    if isinstance(source, str) and ("\n" in source or "=" in source):
        return source, base / "<string>"
    path = Path(source)
    try:
        return path.read_text(encoding="utf-8"), path
    except OSError as e:
        raise _native.ConfigError(f"cannot read {path}: {e.strerror or e}") from None


def as_dict(source: Source, base_dir: str | os.PathLike | None = None) -> tuple[dict, Path]:
    """The source as a dict (a copy) and its path."""
    text, path = toml_source(source, base_dir)
    return _native.toml_to_dict(text, str(path)), path


def read_toml(source: Source, base_dir: str | os.PathLike | None = None) -> dict:
    """A TOML file (or TOML string, or dict: copied) as a dict, e.g. to change a few keys of an
    experiment, site or region file before running it (pass ``base_dir`` = the file's folder
    then, so that its relative paths still resolve)."""
    return as_dict(source, base_dir)[0]
