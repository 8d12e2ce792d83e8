"""Inputs given as a path, a TOML string or a dict, turned into (TOML text, path named in
errors and anchoring relative paths)."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Mapping, Optional, Union

from . import _native
from ._checks import existing

Source = Union[str, os.PathLike, Mapping[str, Any]]


def toml_source(source: Source, base_dir: str | os.PathLike | None = None) -> tuple[str, Path]:
    """TOML text and its path. A ``dict`` is written as TOML (named ``<dict>``), a string holding
    a newline or ``=`` is TOML text (named ``<string>``), anything else is a file path.
    ``base_dir``: the folder relative paths of a dict or string are taken from (default: the
    current folder)."""
    if base_dir is None:
        # A dict from read_toml remembers the folder of the file it came from.
        base_dir = getattr(source, "base_dir", None)
    base = Path(base_dir) if base_dir is not None else Path()
    if isinstance(source, Mapping):
        return _native.dict_to_toml(_eradiate_style(dict(source))), base / "<dict>"
    if isinstance(source, str) and ("\n" in source or "=" in source):
        return source, base / "<string>"
    path = Path(existing(source, "input file"))
    try:
        return path.read_text(encoding="utf-8"), path
    except OSError as e:
        raise _native.ConfigError(f"cannot read {path}: {e.strerror or e}") from None


def _eradiate_style(d: dict) -> dict:
    """Input as Eradiate users write it: a single measure table for ``measures``, and tuples
    or ``range`` objects wherever lists go (the scalar ``wavelengths`` is read by the
    simulator itself)."""

    def lists(v):
        if isinstance(v, Mapping):
            return {k: lists(x) for k, x in v.items()}
        if isinstance(v, (tuple, range, list)):
            return [lists(x) for x in v]
        return v

    out = lists(d)
    if isinstance(out.get("measures"), Mapping):
        out["measures"] = [out["measures"]]
    return out


class TomlDict(dict):
    """A dict read from a TOML file that remembers the file's folder (``base_dir``), so that
    passing it back (to ``run``, ``pics``, ``build_bundle``) resolves its relative paths from
    there, as the file itself would."""

    base_dir: Optional[Path] = None


def as_dict(source: Source, base_dir: str | os.PathLike | None = None) -> tuple[dict, Path]:
    """The source as a dict (a copy) and its path."""
    text, path = toml_source(source, base_dir)
    return _native.toml_to_dict(text, str(path)), path


def read_toml(source: Source, base_dir: str | os.PathLike | None = None) -> dict:
    """A TOML file (or TOML string, or dict: copied) as a dict, e.g. to change a few keys of an
    experiment, site or region file before running it. The dict remembers the folder of the
    file (its ``base_dir`` attribute), so relative paths inside still resolve when it is
    passed back; ``base_dir`` given here or to the function it is passed to overrides it."""
    d, path = as_dict(source, base_dir)
    out = TomlDict(d)
    if base_dir is not None:
        out.base_dir = Path(base_dir)
    elif not isinstance(source, Mapping) and path.name not in ("<string>", "<dict>"):
        out.base_dir = path.parent
    else:
        out.base_dir = getattr(source, "base_dir", None)
    return out
