"""The figure docs/img/grenoble_night.png from a run of examples/night/grenoble_night.toml:
520 nm and 590 nm radiance (log scale) and the 590 nm relative standard error.

    python tools/plot_night.py out/night_render/results.nc docs/img/grenoble_night.png
"""
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.colors as mcolors
import matplotlib.pyplot as plt
import numpy as np
import xarray as xr

ds = xr.open_dataset(sys.argv[1])
wl = list(ds.wavelength.values)
rad, err = ds["dnb_radiance"].values, ds["dnb_radiance_stderr"].values
fig, axes = plt.subplots(1, 3, figsize=(12, 3.8))
for ax, w in zip(axes[:2], (520.0, 590.0)):
    r = rad[wl.index(w)]
    im = ax.imshow(r, cmap="inferno", norm=mcolors.LogNorm(vmin=np.percentile(r, 1), vmax=r.max()))
    ax.set_title(f"{w:.0f} nm radiance (W m⁻² sr⁻¹ nm⁻¹)", fontsize=10)
    fig.colorbar(im, ax=ax)
i = wl.index(590.0)
im = axes[2].imshow(100 * err[i] / rad[i], cmap="viridis", vmin=0, vmax=3)
axes[2].set_title("590 nm relative standard error (%)", fontsize=10)
fig.colorbar(im, ax=axes[2])
for ax in axes:
    ax.set_xticks([])
    ax.set_yticks([])
fig.tight_layout()
fig.savefig(sys.argv[2], dpi=80)
