#!/usr/bin/env bash
# The C++ compiler for the tinybvh peer of the peer benchmark: `tinybvh-rs` compiles tinybvh with `-march=native`,
# which on an AVX-512 machine gives it AVX-512 code (wider registers than the AVX2 kernels of Embree and bvhc it is
# compared with, and instructions callgrind cannot run). This passes every argument on to `c++` (or `$REAL_CXX`),
# with `-march=native` replaced by `-march=x86-64-v3` (AVX2, FMA). Used as
# `CXX=scripts/avx2-cxx.sh RUSTFLAGS="-C target-feature=+avx2,+fma" cargo bench --bench peer --features embree4,tinybvh`.
set -euo pipefail
args=()
for arg in "$@"; do
  if [ "$arg" = "-march=native" ]; then args+=("-march=x86-64-v3"); else args+=("$arg"); fi
done
exec "${REAL_CXX:-c++}" "${args[@]}"
