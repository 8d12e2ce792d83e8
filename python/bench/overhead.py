"""Overhead of the Python package against the command line (BENCHMARKS.md, "Python package").

1. PICS: 50 acquisitions of the Libya-4 site of examples/pics (CKD gas absorption, O3
   continuum, desert aerosols, RPV sand), one a week through 2026, Sentinel-2A band 4, with a
   small per-acquisition workload (ALIS CKD walks, spp = SPP, no target precision) so that
   loading and start-up weigh: one `eosim.pics` call against 50 `simulate pics` processes of
   one acquisition each.
2. One run of about 1 s (examples/rayleigh_lambertian.toml, `--spp` chosen for ~1 s): the
   `simulate run` process against `eosim.run` in a Python process (both whole processes, and
   the `eosim.run` call alone).

Run from the repository root after `bash scripts/setup.sh` and `maturin develop --release`:
    .venv/bin/python python/bench/overhead.py [--spp 500] [--run-spp 700000] [--repeat 3] [--skip-pics]
"""

import argparse
import datetime
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
SIMULATE = REPO / "target" / "release" / "simulate"


def site_text(spp: int) -> str:
    import eosim

    site = eosim.read_toml(REPO / "examples" / "pics" / "libya4_site.toml")
    site.pop("target_rel_stderr", None)
    site["spp"] = spp
    site["integrator"] = {"ckd_walk": "alis"}
    base = REPO / "examples" / "pics"
    site["atmosphere"]["absorption_data"] = str((base / site["atmosphere"]["absorption_data"]).resolve())
    for t in site["atmosphere"].get("cross_sections", []):
        t["file"] = str((base / t["file"]).resolve())
    for t in site["atmosphere"].get("particle_layers", []):
        t["dataset"] = str((base / t["dataset"]).resolve())
    return eosim._native.dict_to_toml(site)


def acquisitions(n=50):
    t0 = datetime.datetime(2026, 1, 1, 9, 45)
    return [
        {"time_utc": (t0 + datetime.timedelta(days=7 * k)).strftime("%Y-%m-%dT%H:%M:%SZ"),
         "vza": 5.2, "vaa": 103.0, "srf": "sentinel_2a-msi-4"}
        for k in range(n)
    ]


def timed(cmd):
    t = time.perf_counter()
    subprocess.run(cmd, check=True, capture_output=True)
    return time.perf_counter() - t


def pics_bench(spp, tmp: Path):
    site = tmp / "site.toml"
    site.write_text(site_text(spp))
    acqs = acquisitions()
    # 50 CLI processes, one acquisition each.
    t_cli = 0.0
    for k, a in enumerate(acqs):
        csv = tmp / f"acq{k}.csv"
        csv.write_text("time_utc,vza,vaa,srf\n" + f"{a['time_utc']},{a['vza']},{a['vaa']},{a['srf']}\n")
        t_cli += timed([str(SIMULATE), "-q", "pics", str(csv), "--site", str(site), "-o", str(tmp / f"cli{k}")])
    # One Python process: import, load and 50 acquisitions in one sweep.
    code = (
        "import eosim, json, sys, time; t=time.perf_counter(); "
        f"ds=eosim.pics({str(site)!r}, json.load(open({str(tmp / 'acq.json')!r})), progress=False); "
        "print(time.perf_counter()-t)"
    )
    import json

    (tmp / "acq.json").write_text(json.dumps(acqs))
    t = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True)
    t_py = time.perf_counter() - t
    # For reference: the CLI's own batch, one `simulate pics` of all 50.
    all_csv = tmp / "acq_all.csv"
    all_csv.write_text("time_utc,vza,vaa,srf\n" + "".join(
        f"{a['time_utc']},{a['vza']},{a['vaa']},{a['srf']}\n" for a in acqs))
    t_batch = timed([str(SIMULATE), "-q", "pics", str(all_csv), "--site", str(site), "-o", str(tmp / "cli_all")])
    return t_cli, t_py, float(out.stdout.split()[-1]), t_batch


def run_bench(spp, tmp: Path):
    exp = REPO / "examples" / "rayleigh_lambertian.toml"
    t_cli = timed([str(SIMULATE), "-q", "run", str(exp), "-o", str(tmp / "run_cli"), "--spp", str(spp)])
    # In a Python session (eosim imported): the call alone, without and with written products.
    code = (
        "import time, eosim; t1=time.perf_counter(); "
        f"eosim.run({str(exp)!r}, spp={spp}, progress=False); t2=time.perf_counter(); "
        f"eosim.run({str(exp)!r}, spp={spp}, progress=False, output={str(tmp / 'run_py')!r}); "
        "t3=time.perf_counter(); print(t2-t1, t3-t2)"
    )
    out = subprocess.run([sys.executable, "-c", code], check=True, capture_output=True, text=True)
    call, call_out = map(float, out.stdout.split())
    # A whole Python process doing what the CLI process does: start, import, run, write.
    t_py = timed([sys.executable, "-c", f"import eosim; eosim.run({str(exp)!r}, spp={spp}, "
                  f"progress=False, output={str(tmp / 'run_py2')!r})"])
    t_imp = timed([sys.executable, "-c", "import eosim"])
    return t_cli, t_py, t_imp, call, call_out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--spp", type=int, default=500)
    ap.add_argument("--run-spp", type=int, default=700_000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--skip-pics", action="store_true", help="only the single-run comparison")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d)
        rows = [] if args.skip_pics else [pics_bench(args.spp, tmp) for _ in range(args.repeat)]
        for t_cli, t_py, t_call, t_batch in rows:
            print(f"pics 50 acquisitions (spp {args.spp}, ALIS): 50 CLI calls {t_cli:.2f} s, "
                  f"Python process {t_py:.2f} s (eosim.pics call {t_call:.2f} s): {t_cli / t_py:.1f}x; "
                  f"one `simulate pics` of all 50: {t_batch:.2f} s")
        if rows:
            med = statistics.median(r[0] / r[1] for r in rows)
            print(f"pics median speed-up {med:.1f}x")
        rows = [run_bench(args.run_spp, tmp) for _ in range(args.repeat)]
        for t_cli, t_py, imp, call, call_out in rows:
            print(f"one run (--spp {args.run_spp}): CLI process {t_cli:.3f} s; Python: eosim.run {call:.3f} s "
                  f"({100 * (call / t_cli - 1):+.1f} %), with output= {call_out:.3f} s "
                  f"({100 * (call_out / t_cli - 1):+.1f} %); whole Python process {t_py:.3f} s "
                  f"({100 * (t_py / t_cli - 1):+.1f} %; `python -c 'import eosim'` alone {imp:.3f} s)")
        med = statistics.median(r[3] / r[0] - 1 for r in rows)
        med_out = statistics.median(r[4] / r[0] - 1 for r in rows)
        print(f"one run median: eosim.run {100 * med:+.1f} %, with output= {100 * med_out:+.1f} % against the CLI process")


if __name__ == "__main__":
    main()
