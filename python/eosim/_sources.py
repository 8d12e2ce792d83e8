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
    path = Path(existing(source, "input file", "a path, a TOML string or a dict"))
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
    """Read a TOML file (an experiment, a site or a region) into a dict.

    Use it to change a few keys of a file before running it. The dict remembers the folder
    of the file (its ``base_dir`` attribute), so the file's relative paths (phase tables,
    profiles, DEMs) still resolve when the dict is passed to :func:`run`, :func:`load`,
    :func:`pics` or :func:`build_bundle`, whatever the current folder; a ``base_dir`` given
    to those functions wins.

    Parameters
    ----------
    source : str, os.PathLike or dict
        The path of a TOML file, TOML text (a string holding ``=`` or a newline), or a dict
        (copied).
    base_dir : str or os.PathLike, optional
        The folder to remember instead of the file's (for a string or a dict, the folder
        their relative paths are taken from).

    Returns
    -------
    dict
        The TOML document as nested dicts and lists (a ``dict`` subclass with a
        ``base_dir`` attribute: a ``pathlib.Path``, or None for a string or dict without
        `base_dir`).

    Raises
    ------
    TypeError
        If `source` is not a path, a string or a dict, or a dict's value has no TOML form.
    InputFileNotFoundError
        If the file does not exist.
    ConfigError
        If the text is not valid TOML (the message gives the line and column), or the file
        cannot be read.

    See Also
    --------
    load : Validate an experiment (from the dict, a file or a string).

    Examples
    --------
    >>> import pathlib, tempfile
    >>> import eosim
    >>> folder = tempfile.TemporaryDirectory()
    >>> f = pathlib.Path(folder.name) / "exp.toml"
    >>> _ = f.write_text('''
    ... seed = 3
    ... [spectral]
    ... wavelengths = [550.0]
    ... [surface]
    ... type = "lambertian"
    ... reflectance = 0.3
    ... [illumination]
    ... type = "directional"
    ... zenith = 30.0
    ... [[measures]]
    ... id = "toa"
    ... type = "mdistant"
    ... azimuth = 0.0
    ... zeniths = [0.0]
    ... spp = 1000
    ... ''')
    >>> d = eosim.read_toml(f)
    >>> d["seed"], d["surface"]["reflectance"], d["measures"][0]["id"]
    (3, 0.3, 'toa')
    >>> d.base_dir == f.parent
    True
    >>> d["surface"]["reflectance"] = 0.5
    >>> ds = eosim.run(d, threads=1, progress=False)
    >>> float(ds.brf.squeeze())                     # no atmosphere: the ground's BRF
    0.5
    >>> folder.cleanup()
    """
    d, path = as_dict(source, base_dir)
    out = TomlDict(d)
    if base_dir is not None:
        out.base_dir = Path(base_dir)
    elif not isinstance(source, Mapping) and path.name not in ("<string>", "<dict>"):
        out.base_dir = path.parent
    else:
        out.base_dir = getattr(source, "base_dir", None)
    return out
