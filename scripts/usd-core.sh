#!/usr/bin/env bash
# Installs Pixar's USD Python bindings (usd-core, from PyPI) and numpy into target/usd/venv: the oracle that
# tests/suite/usd_oracle.rs compares bvhc's OpenUSD import with. Exits non-zero when they cannot be installed.
set -euo pipefail
cd "$(dirname "$0")/.."
venv=target/usd/venv
if ! "$venv/bin/python" -c "import pxr.Usd, numpy" >/dev/null 2>&1; then
  rm -rf "$venv"
  python3 -m venv "$venv"
  "$venv/bin/pip" install --quiet --disable-pip-version-check usd-core numpy
fi
"$venv/bin/python" -c "from pxr import Usd; print('usd-core', '.'.join(map(str, Usd.GetVersion())))"
