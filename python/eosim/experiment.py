"""Experiments: load (file, TOML string or dict), inspect, run into an ``xarray.Dataset``."""

from __future__ import annotations

import os
from typing import Callable, Optional, Union

import xarray as xr

from . import _native
from ._checks import count, existing
from ._dataset import to_dataset
from ._progress import reporter
from ._sources import Source, toml_source

Progress = Union[bool, Callable[[int, int], None], None]


class Experiment:
    """A validated experiment (every key checked, every input file read, the scene built).

    Load one with :func:`load` (or ``Experiment.from_file``, ``from_toml``, ``from_dict``); run it
    as often as needed with :meth:`run`: nothing is read again.
    """

    def __init__(self, native: _native.Experiment):
        self._native = native

    @classmethod
    def from_file(cls, path: Union[str, os.PathLike], *, spp: Optional[int] = None) -> "Experiment":
        """An experiment file; relative paths inside are taken from its folder."""
        text, p = toml_source(existing(path, "experiment file"))
        return cls(_native.load_experiment(text, p, count("spp", spp)))

    @classmethod
    def from_toml(cls, text: str, *, base_dir=None, spp: Optional[int] = None) -> "Experiment":
        """TOML text (named ``<string>`` in errors); relative paths from ``base_dir``."""
        from pathlib import Path

        if not isinstance(text, str):
            raise TypeError(f"text must be a str of TOML, not {type(text).__name__}")
        p = (Path(base_dir) if base_dir is not None else Path()) / "<string>"
        return cls(_native.load_experiment(text, p, count("spp", spp)))

    @classmethod
    def from_dict(cls, d: dict, *, base_dir=None, spp: Optional[int] = None) -> "Experiment":
        """A dict with the keys of an experiment file (named ``<dict>`` in errors)."""
        if not isinstance(d, dict):
            raise TypeError(f"d must be a dict, not {type(d).__name__}")
        text, p = toml_source(d, base_dir)
        return cls(_native.load_experiment(text, p, count("spp", spp)))

    @property
    def wavelengths(self) -> list:
        """The run's wavelengths, nm."""
        return self._native.wavelengths

    @property
    def measures(self) -> list:
        """The measures' ids."""
        return self._native.measures

    @property
    def seed(self) -> int:
        return self._native.seed

    @property
    def text(self) -> str:
        """The experiment's TOML text (as written into ``results.nc``)."""
        return self._native.text

    @property
    def path(self):
        """The file the experiment came from (``<dict>`` or ``<string>`` otherwise)."""
        return self._native.path

    def memory(self) -> dict:
        """Bytes the run needs: ``{"results", "scene", "total"}``."""
        return self._native.memory()

    def run(
        self,
        *,
        progress: Progress = True,
        threads: Optional[int] = None,
        output: Union[str, os.PathLike, None] = None,
    ) -> xr.Dataset:
        """Run and return the results as ``results.nc`` holds them.

        ``progress``: True (a tqdm bar in Jupyter or the terminal), False, or a callable
        ``(walks_done, walks_total)``. ``threads``: worker threads (None: all cores; results do
        not depend on it). ``output``: a folder to also write the command line's products into
        (``results.nc``, ``results.csv``, GeoTIFFs, PNG quicklooks); None writes nothing.
        Ctrl-C (KeyboardInterrupt) stops the run within one block of samples.
        """
        out = None if output is None else os.fspath(output)
        threads = count("threads", threads)
        with reporter(progress, "simulate", "walks") as cb:
            raw = self._native.run(cb, threads, out)
        return to_dataset(raw)

    def __repr__(self) -> str:
        return (
            f"Experiment({str(self.path)!r}: {len(self.wavelengths)} wavelength(s), "
            f"measures {self.measures}, seed {self.seed})"
        )


def load(source: Source, *, base_dir=None, spp: Optional[int] = None) -> Experiment:
    """An experiment from a file path, a TOML string or a dict (see ``_sources.toml_source``).
    Invalid input raises :class:`eosim.ConfigError` naming the key path."""
    text, p = toml_source(source, base_dir)
    return Experiment(_native.load_experiment(text, p, count("spp", spp)))


def run(
    source: Union[Source, Experiment],
    *,
    progress: Progress = True,
    threads: Optional[int] = None,
    output=None,
    spp: Optional[int] = None,
    base_dir=None,
) -> xr.Dataset:
    """Load (unless given an :class:`Experiment`) and run; see :meth:`Experiment.run`."""
    count("spp", spp)
    count("threads", threads)
    exp = source if isinstance(source, Experiment) else load(source, base_dir=base_dir, spp=spp)
    return exp.run(progress=progress, threads=threads, output=output)
