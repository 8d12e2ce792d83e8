#!/usr/bin/env python3
"""Plot IPRT A5 (polarized water cloud, τ 5, SZA 50°) against MYSTIC: I, Q, U along the
principal plane with ±2σ, and I's relative difference (docs/img/iprt_a5.png). Ours:
validation/iprt_a5/a5_results.csv, `examples/iprt_a5_cloud.toml` run with spp = 3 000 000
(BENCHMARKS.md, "Peaked phase functions"). Reference: simulator/tests/data/iprt/a5_pp_toa.dat
(radiance for F0 = 1, converted to BRF units by π/μ0; U of opposite sign, see
simulator/tests/iprt_a.rs). Needs matplotlib; from the repo root:

    python3 tools/plots/iprt_a5_plot.py
"""
import csv
import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

K = math.pi / math.cos(math.radians(50.0))
ref = []
with open("simulator/tests/data/iprt/a5_pp_toa.dat") as f:
    for line in f:
        if line.startswith("#") or not line.strip():
            continue
        v = [float(x) for x in line.split()]
        va, phi = v[3], v[4]
        if va > 179.5 and phi != 0.0:
            continue
        ref.append({"va": va, "phi": phi, "iqu": [K * x for x in v[5:8]], "std": [K * x for x in v[9:12]]})
ours = list(csv.DictReader(open("validation/iprt_a5/a5_results.csv")))
assert len(ours) == len(ref)


def signed(r):
    # Signed view zenith: negative for IPRT phi = 180°, positive for phi = 0°.
    vza = 180.0 - r["va"]
    return -vza if r["phi"] == 180.0 else vza


xs = [signed(r) for r in ref]
order = sorted(range(len(xs)), key=lambda i: xs[i])
fig, axes = plt.subplots(2, 2, figsize=(10, 7))
for c, (name, col, sign) in enumerate([("I", "brf", 1.0), ("Q", "brf_q", 1.0), ("U", "brf_u", -1.0)]):
    ax = axes.flat[c]
    x = [xs[i] for i in order]
    rv = [ref[i]["iqu"][c] for i in order]
    ov = [sign * float(ours[i][col]) for i in order]
    oe = [float(ours[i][col + "_stderr"]) for i in order]
    ax.plot(x, rv, "k-", lw=1, label="MYSTIC")
    ax.errorbar(x, ov, yerr=[2 * e for e in oe], fmt="o", ms=3, color="C3", label="ours ±2σ")
    ax.set_title(f"{name} (BRF units)")
    ax.set_xlabel("view zenith [°] (negative: IPRT φ = 180°)")
    ax.legend(fontsize=8)
ax = axes.flat[3]
x = [xs[i] for i in order]
rel = [100 * (float(ours[i]["brf"]) / ref[i]["iqu"][0] - 1) for i in order]
err = [200 * float(ours[i]["brf_stderr"]) / ref[i]["iqu"][0] for i in order]
ax.errorbar(x, rel, yerr=err, fmt="o", ms=3, color="C3")
ax.axhline(0, color="k", lw=0.8)
rms = math.sqrt(sum(r * r for r in rel) / len(rel))
ax.set_title(f"I: ours/MYSTIC − 1 [%] (RMS {rms:.2f} %)")
ax.set_xlabel("view zenith [°]")
fig.suptitle("IPRT A5 water cloud τ 5, SZA 50°, 3·10⁶ photons with DDIS (2 min, 1 core)")
fig.tight_layout()
fig.savefig("docs/img/iprt_a5.png", dpi=110)
print(f"wrote docs/img/iprt_a5.png; I relative RMS {rms:.3f} %")
