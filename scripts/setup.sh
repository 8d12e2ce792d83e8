#!/usr/bin/env bash
# Idempotent set-up of a Debian machine for this workspace: system libraries (netCDF, HDF5,
# GDAL headers), then the Rust crates and a release build, then the Python virtual environment
# `.venv/` of the Python package (python/requirements-dev.txt; built and tested by
# scripts/test-python.sh). Safe to run again: it installs only
# what is missing. Used by the README's first command and by .ci/run.
set -euo pipefail

cd "$(dirname "$0")/.."

# slurm-wlm and munge: the Slurm test (tests/slurm.rs) starts a one-node cluster on this machine.
PKGS=(pkg-config libnetcdf-dev libhdf5-dev netcdf-bin libgdal-dev slurm-wlm munge)
# The Python package needs python3 (>= 3.10) with venv and ensurepip (Debian splits them off).
if ! python3 -c "import venv, ensurepip" >/dev/null 2>&1; then PKGS+=(python3 python3-venv); fi

missing=()
for p in "${PKGS[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
    echo "setup: installing Debian packages: ${missing[*]}"
    SUDO=""
    if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
else
    echo "setup: Debian packages present"
fi

if ! command -v cargo >/dev/null 2>&1; then
    echo "setup: cargo not found. Install a Rust toolchain >= 1.85 (https://rustup.rs) and run again." >&2
    exit 1
fi

# fmt and clippy run in CI (.ci/run); rustup toolchains may lack them.
if command -v rustup >/dev/null 2>&1; then
    for c in rustfmt clippy; do
        rustup component list --installed 2>/dev/null | grep -q "^$c" || rustup component add "$c" >/dev/null 2>&1 || echo "setup: could not add the $c component" >&2
    done
fi

echo "setup: fetching crates and building (release)"
cargo fetch --locked 2>/dev/null || cargo fetch
cargo build --release --workspace --bins

# The Python package's environment: created once, its packages installed again only when
# python/requirements-dev.txt changes.
if [ ! -x .venv/bin/python ]; then
    echo "setup: creating .venv (Python package)"
    python3 -m venv .venv
fi
REQ=python/requirements-dev.txt
if ! cmp -s "$REQ" .venv/.requirements-installed; then
    echo "setup: installing Python packages from $REQ into .venv"
    .venv/bin/python -m pip install -q --upgrade pip
    .venv/bin/python -m pip install -q -r "$REQ"
    cp "$REQ" .venv/.requirements-installed
else
    echo "setup: .venv up to date"
fi
echo "setup: done"
