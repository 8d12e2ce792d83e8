#!/usr/bin/env bash
# The Python package's tests (part of the README's test command and of .ci/run): builds and
# installs `eosim` into .venv/ (maturin develop --release: reuses the workspace's release
# build in target/), runs its pytest suite (python/tests/, docstring examples included),
# builds the API page with pdoc (target/python-api/, failing on any warning) and executes the
# notebooks of examples/python/ (nbmake). Needs the set-up step (scripts/setup.sh: .venv and its packages).
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
# The API page: the numpydoc docstrings rendered by pdoc into target/python-api/ (not
# committed; open target/python-api/eosim.html). pdoc reports problems on stderr ("Warn: ...")
# and still exits 0, so any warning line fails the step. One page: the module eosim.pics,
# listed because its name is the function eosim.pics's, is left out.
rm -rf target/python-api
mkdir -p target
if ! python -m pdoc --docformat numpy -o target/python-api eosim '!eosim.pics' 2> target/python-api.log; then
    cat target/python-api.log >&2
    echo "test-python: pdoc failed" >&2
    exit 1
fi
if grep -qi "warn" target/python-api.log; then
    cat target/python-api.log >&2
    echo "test-python: pdoc warned (above): fix the docstrings" >&2
    exit 1
fi
echo "test-python: API page in target/python-api/eosim.html"
# The notebooks run from their folder, as a user runs them; nbmake fails on any cell error.
python -m pytest -q --nbmake --nbmake-timeout=600 examples/python
