#!/usr/bin/env bash
# Instructions a ray, bvhc against Embree (AVX2 kernels on both sides), counted by callgrind inside the peer
# benchmark's measured pass only: `scripts/peer-instructions.sh [scenes] [rays]`, e.g. `kitchen,engine 100000`.
# Needs valgrind and the benchmark built with an Embree feature (scripts/embree4.sh, then
# `cargo bench --bench peer --features embree4 --no-run`); the scenes' conversions are cached in target/peer.
set -euo pipefail
cd "$(dirname "$0")/.."
scenes="${1:-kitchen,engine}"
rays="${2:-100000}"
feature="${BVHC_PEER_FEATURE:-embree4}"
# `BVHC_PEER_CONTENDERS=bvhc` counts bvhc alone (a before/after gate for a loader change). With
# `BVHC_PEER_TINYBVH=1` the benchmark is built with tinybvh's BVH8_CPU as well (AVX2 and FMA for the whole build, in
# target/tinybvh; docs/kernel-peer.md, "A second peer"), for `BVHC_PEER_CONTENDERS="bvhc tinybvh embree"`
# (tinybvh: closest hits only).
contenders="${BVHC_PEER_CONTENDERS:-bvhc embree}"
build=(cargo bench --bench peer --features "$feature" --no-run --message-format=json)
if [ "${BVHC_PEER_TINYBVH:-}" = 1 ]; then
  export CXX="$PWD/scripts/avx2-cxx.sh" RUSTFLAGS="-C target-feature=+avx2,+fma" CARGO_TARGET_DIR=target/tinybvh
  build=(cargo bench --bench peer --features "$feature,tinybvh" --no-run --message-format=json)
fi
binary=$("${build[@]}" 2>/dev/null \
  | python3 -c 'import json,sys; print([m["executable"] for m in map(json.loads, sys.stdin) if m.get("executable") and "peer" in m["executable"]][-1])')
out=$(mktemp -d)
echo "| scene | rays | query | contender | instructions a ray |"
echo "|---|---|---|---|---|"
IFS=',' read -ra scene_list <<< "$scenes"
for scene in "${scene_list[@]}"; do
  # Convert once natively (callgrind would take minutes for it).
  BVHC_PEER_SCENES="$scene" BVHC_PEER_ONLY=bvhc BVHC_BENCH_RAYS=1 "$binary" --bench >/dev/null
  for set in incoherent primary; do
    for query in closest any; do
      for contender in $contenders; do
        if [ "$contender" = tinybvh ] && [ "$query" = any ]; then continue; fi
        file="$out/$scene-$set-$query-$contender.out"
        BVHC_PEER_SCENES="$scene" BVHC_PEER_ONLY="$contender" BVHC_PEER_SET="$set" BVHC_PEER_QUERY="$query" \
          BVHC_BENCH_RAYS="$rays" BVHC_PEER_CAMERA=400x250 \
          valgrind --tool=callgrind --toggle-collect='*measured_pass*' --callgrind-out-file="$file" \
          "$binary" --bench >/dev/null 2>&1
        total=$(grep -m1 '^totals:' "$file" | awk '{print $2}')
        count=$([ "$set" = primary ] && echo 100000 || echo "$rays")
        echo "| $scene | $set | $query | $contender | $(awk -v t="$total" -v c="$count" 'BEGIN { printf "%.1f", t / c }') |"
      done
    done
  done
done
