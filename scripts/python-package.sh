#!/usr/bin/env bash
# Builds the Python package's wheel (crates/bvhc-py, with maturin) and installs it into a virtual environment, as a
# user would:
#   scripts/python-package.sh [VENV]       (default: target/python/venv)
# The wheel lands in target/python/wheels (one abi3 wheel for every CPython from 3.9); tests/suite/python_package.rs
# runs the package's pytest suite with that environment's Python.
set -euo pipefail
cd "$(dirname "$0")/.."
venv="${1:-target/python/venv}"
wheels="target/python/wheels"
python3 -m venv "$venv"
"$venv/bin/python" -m pip install -q "maturin>=1.5,<2" numpy pytest trimesh
# Dask's distributed scheduler, for convert_many's cluster tests; they say SKIPPED where it cannot be installed.
"$venv/bin/python" -m pip install -q "dask[distributed]" || echo "dask[distributed] not installed: its tests are SKIPPED"
rm -rf "$wheels"
CARGO_TARGET_DIR="$PWD/target/python/cargo" "$venv/bin/maturin" build --release -q \
  --manifest-path crates/bvhc-py/Cargo.toml --interpreter "$venv/bin/python" -o "$wheels"
"$venv/bin/python" -m pip install -q --force-reinstall --no-deps "$wheels"/bvhc-*.whl
wheel=$(ls "$wheels"/bvhc-*.whl)
echo "installed $(basename "$wheel") ($(du -k "$wheel" | cut -f1) KiB) into $venv"
