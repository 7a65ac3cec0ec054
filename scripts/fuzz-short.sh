#!/usr/bin/env bash
# Short fuzzing run of the targets in fuzz/ (FUZZ_TARGETS, default all; cargo fuzz, nightly,
# AddressSanitizer): FUZZ_SECONDS per target (default 10), from the fixed seed FUZZ_SEED
# (default 1), so that a run explores the same inputs on every machine (a faster one goes
# further along the same sequence). The FCLib reader starts from a few small files of ../shared/data/fclib copied
# to a temporary corpus; the other targets from an empty one. A crash, a leak (leaks inside
# libhdf5 itself are suppressed: fuzz/lsan.supp) or a hang (an input over 10 s) fails the
# run; libFuzzer writes the input to fuzz/artifacts/<target>/ to reproduce with
# `cargo +nightly fuzz run <target> <file>`.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${FUZZ_SECONDS:-10}
seed=${FUZZ_SEED:-1}
targets=${FUZZ_TARGETS:-problem_csc c_api fclib_read}
export LSAN_OPTIONS="suppressions=$PWD/fuzz/lsan.supp:print_suppressions=0"
# A corrupt file can make libhdf5 ask malloc for about 1e18 bytes; malloc then returns NULL
# as in production (what libhdf5 does with it is its own: docs/limits.md). A Rust allocation
# that fails still aborts, and is reported.
export ASAN_OPTIONS="allocator_may_return_null=1"

if ! rustup toolchain list | grep -q '^nightly'; then
  rustup toolchain install nightly --profile minimal
fi
if ! cargo fuzz --version >/dev/null 2>&1; then
  cargo install cargo-fuzz --locked
fi

corpus=$(mktemp -d)
trap 'rm -rf "$corpus"' EXIT
mkdir -p "$corpus/fclib_read" "$corpus/problem_csc" "$corpus/c_api"
data=../shared/data/fclib
for f in local/FrictionContact3D_1c.hdf5 local/FC3D_Example1.hdf5 local/Rover4396.hdf5 \
         global/Box_Stacks-i0122-82-5.hdf5; do
  if [[ -f $data/$f ]]; then cp "$data/$f" "$corpus/fclib_read/"; fi
done

cd fuzz
cargo +nightly fuzz build -O
for target in $targets; do
  echo "fuzz-short: $target, $seconds s"
  cargo +nightly fuzz run -O "$target" "$corpus/$target" -- \
    -max_total_time="$seconds" -seed="$seed" -timeout=10 -rss_limit_mb=4096 -print_final_stats=1
done
