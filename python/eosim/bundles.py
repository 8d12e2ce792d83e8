"""Scene bundles: build one from a region (file, TOML string or dict), open one to inspect it."""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

from . import _native
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
    d = _native.open_bundle(os.fspath(path))
    return Bundle(Path(path), **d)


def build_bundle(region: Source, output, *, force: bool = False, base_dir=None) -> Bundle:
    """Build the bundle of ``region`` (a region file, TOML string or dict: ``docs/region.md``)
    into folder ``output`` (``force``: replace an existing bundle) and open it."""
    text, p = toml_source(region, base_dir)
    _native.build_bundle(text, p, os.fspath(output), force)
    return open_bundle(output)
