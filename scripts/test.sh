#!/usr/bin/env bash
# Builds cadmm and runs every test: Rust (unit, integration, C programs built by `cc`,
# header drift, FCLib solves checked by an independent measure) in release mode, then the
# CMake build with CTest (C and C++ tests against SuiteSparse and Eigen, install-consumer
# test, Valgrind runs of the C tests).
set -euo pipefail
cd "$(dirname "$0")/.."
jobs=${CADMM_JOBS:-2}

bash scripts/install-deps.sh

cargo fmt --check
cargo clippy --all-features --all-targets -- -D warnings
cargo test --release --all-features

cmake -S . -B build -DCMAKE_BUILD_TYPE=Release -DCADMM_VALGRIND=ON
cmake --build build -j "$jobs"
ctest --test-dir build --output-on-failure -j "$jobs"
