#!/usr/bin/env bash
# The Python package's tests (part of the README's test command and of .ci/run): builds and
# installs `eosim` into .venv/ (maturin develop --release: reuses the workspace's release
# build in target/), runs its pytest suite (python/tests/) and executes the notebooks of
# examples/python/ (nbmake). Needs the set-up step (scripts/setup.sh: .venv and its packages).
set -euo pipefail
cd "$(dirname "$0")/.."
if [ ! -x .venv/bin/python ]; then
    echo "test-python: .venv missing: run bash scripts/setup.sh first" >&2
    exit 1
fi
export VIRTUAL_ENV="$PWD/.venv"
export PATH="$VIRTUAL_ENV/bin:$PATH"
(cd python && maturin develop --release --quiet)
python -m pytest -q python/tests
# The notebooks run from their folder, as a user runs them; nbmake fails on any cell error.
python -m pytest -q --nbmake --nbmake-timeout=600 examples/python
