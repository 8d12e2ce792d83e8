#!/usr/bin/env bash
# Copies the experiment-file reference docs/experiment.md into the Python package
# (python/eosim/data/experiment.md), where `eosim.keys()` reads its key tables: the wheel ships
# no docs/ folder, and a symbolic link would not survive it. Run after editing
# docs/experiment.md; python/tests/test_keys.py fails while the two differ.
set -euo pipefail
cd "$(dirname "$0")/.."
cp docs/experiment.md python/eosim/data/experiment.md
echo "sync-python-docs: python/eosim/data/experiment.md updated from docs/experiment.md"
