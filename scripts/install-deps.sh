#!/usr/bin/env bash
# Installs what building and testing cadmm needs on a Debian machine, when missing:
# cmake and pkg-config (C/CMake side), HDF5 (FCLib files), SuiteSparse and Eigen (the C
# reference-solve tests), Bullet and ODE (the engine integrations), valgrind (memory checks of the C tests), Siconos numerics (the
# peer the benchmarks compare against), a font for the benchmark plots, matplotlib for the
# integrations' trace plots (integrations/*/plot_trace.py), the Python
# packages of the error checker and of the Python package's tests (with venv, where they
# run), and mdBook for the docs/ book.
set -euo pipefail

debs=(cmake pkg-config libhdf5-dev libsuitesparse-dev libeigen3-dev valgrind fonts-dejavu-core
      libbullet-dev libode-dev python3-matplotlib
      libsiconos-numerics-dev python3-siconos python3-h5py python3-numpy python3-scipy python3-venv
      openmpi-bin libopenmpi-dev libclang-dev)
missing=()
for d in "${debs[@]}"; do
  dpkg-query -W -f='${Status}' "$d" 2>/dev/null | grep -q "install ok installed" || missing+=("$d")
done
if ((${#missing[@]})); then
  SUDO=""
  [[ $(id -u) -ne 0 ]] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${missing[@]}"
fi
# The first python3 on PATH runs ../shared/tools/fc_error.py in the tests.
if ! python3 -c "import numpy, scipy, h5py" 2>/dev/null; then
  python3 -m pip install --quiet numpy scipy h5py
fi
# mdBook builds the docs/ book in .ci/run: built once from crates.io (about 2 minutes on
# 2 cores) and kept in ~/.cargo/bin; without the web server, which the build does not use.
if ! command -v mdbook >/dev/null && [[ ! -x ${CARGO_HOME:-$HOME/.cargo}/bin/mdbook ]]; then
  cargo install mdbook --locked --version 0.4.52 --no-default-features --features search
fi
