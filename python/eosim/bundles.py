"""Scene bundles: build one from a region (file, TOML string or dict), open one to inspect it."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

from . import _native
from ._checks import existing, flag
from ._sources import Source, toml_source


@dataclass(frozen=True)
class Bundle:
    """A scene bundle on disk (``docs/bundle.md``), read from its manifest."""

    path: Path
    manifest: dict = field(repr=False)
    summary: str = field(repr=False)
    disk_bytes: int = 0
    instanced_triangles: int = 0
    flattened_triangles: float = 0.0

    @property
    def crs(self) -> str:
        """EPSG code (``EPSG:32631``), PROJ string or WKT of the working CRS."""
        c = self.manifest["crs"]
        if c.get("epsg") is not None:
            return f"EPSG:{c['epsg']}"
        return c.get("proj") or c["wkt"]

    @property
    def extent(self) -> dict:
        """``min``/``max`` (m, working frame), ``lon_lat_bbox`` (deg), ``height_range`` (m)."""
        return self.manifest["extent"]

    @property
    def materials(self) -> list:
        """The materials: index, name, BRDF (dict), land-cover class codes."""
        return self.manifest["materials"]

    @property
    def memory(self) -> dict:
        """Sizes: bytes on disk, triangles stored (terrain + templates) and if flattened."""
        return {
            "disk_bytes": self.disk_bytes,
            "instanced_triangles": self.instanced_triangles,
            "flattened_triangles": self.flattened_triangles,
        }

    def __str__(self) -> str:
        return self.summary


def open_bundle(path) -> Bundle:
    """Open (the manifest, files checked present) the bundle in folder ``path``."""
    d = _native.open_bundle(existing(path, "bundle folder"))
    return Bundle(Path(path), **d)


def build_bundle(region: Source, output, *, force: bool = False, base_dir=None) -> Bundle:
    """Build the bundle of ``region`` (a region file, TOML string or dict: ``docs/region.md``)
    into folder ``output`` (``force``: replace an existing bundle) and open it."""
    flag("force", force)
    if not isinstance(output, (str, os.PathLike)):
        raise TypeError(f"output must be a folder path, not {type(output).__name__}")
    text, p = toml_source(region, base_dir)
    if os.path.exists(os.fspath(output)) and not force:
        import errno

        raise OutputExistsError(
            errno.EEXIST,
            "output folder already exists (pass force=True to replace a bundle)",
            os.fspath(output),
        )
    _native.build_bundle(text, p, os.fspath(output), force)
    return open_bundle(output)


class OutputExistsError(FileExistsError, _native.SimulationError):
    """``build_bundle`` into an existing folder without ``force=True``. Both a
    ``FileExistsError`` and an :class:`eosim.SimulationError`."""
