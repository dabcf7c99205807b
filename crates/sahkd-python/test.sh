#!/usr/bin/env bash
# Builds the `sahkd` Python package from this crate into a virtual environment and runs its
# pytest suite. One command for a fresh machine (needs python3 with venv, cargo, and PyPI):
#
#   crates/sahkd-python/test.sh [VENV] [-- PYTEST ARGS...]
#
# VENV defaults to $SAHKD_PYTHON_VENV, else <workspace>/target/python-venv; it is created if
# missing and reused otherwise. PYTHON picks the interpreter that creates it (default python3).
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/../.." && pwd)"
venv="${SAHKD_PYTHON_VENV:-$root/target/python-venv}"
if [ $# -gt 0 ] && [ "$1" != "--" ]; then venv="$1"; shift; fi
[ "${1:-}" = "--" ] && shift

if [ ! -x "$venv/bin/python" ]; then
    "${PYTHON:-python3}" -m venv "$venv"
fi
py="$venv/bin/python"
# trimesh's pure-Python ray intersector (the tests' reference) needs rtree; dask[distributed]
# runs the sahkd.dask tests on a local cluster (they skip, saying so, where it is missing).
"$py" -m pip install --quiet --disable-pip-version-check "maturin>=1.9.4,<2" numpy pytest trimesh rtree \
    "dask[distributed]>=2024" "mypy>=1.10,<2"
(cd "$here" && VIRTUAL_ENV="$venv" nice -n 10 "$venv/bin/maturin" develop --release --quiet)
cd "$here"
"$py" -m pytest tests -q "$@"
# The stubs (python/sahkd/_sahkd.pyi) against the built module, and a typed program using
# every call against the stubs; then the program itself, whose answers are checked.
"$py" -m mypy.stubtest sahkd._sahkd
"$py" -m mypy --strict typed/example.py
"$py" typed/example.py
