#!/usr/bin/env bash
# bvhc against Embree 4.4 two ways on the same scenes, triangles and rays, one thread, so that both figures come
# from one command: in process (benches/peer.rs: the Rust API, `Tracer::trusting_rays`, against Embree through
# Rust FFI) and from outside (benches/c/embree_peer.c: a C program calling the installed libbvhc, checked and
# unchecked, against Embree's C API). Medians of interleaved rounds in each; docs/kernel-peer.md reads them.
#
#   scripts/peer-outside.sh [SCENES] [RAYS]      # e.g. kitchen,engine 200000 (defaults: kitchen,engine,toy car)
#   PEER_TABLES=batches scripts/peer-outside.sh   # only the batch table (single, batches, points, in-process: any set)
#
# The points table (benches/c/embree_points.c) times bvhc_closest_points against rtcPointQuery with a
# closest-point callback, points near the surface and uniform in the box (PEER_POINTS of each, default 200000).
#
# The batch table (benches/c/embree_batches.c) times bvhc's batch calls against Embree's best call on camera,
# ambient-occlusion, shadow and incoherent workloads made from each scene's box.
#
# Needs a C compiler, pkg-config and python3 (for scripts/embree4.sh); installs the C library into
# target/c-library/prefix and Embree into target/embree4 when they are not there. Not used by tests or CI.
set -euo pipefail
cd "$(dirname "$0")/.."
scenes="${1:-kitchen,engine,toy car}"
rays="${2:-200000}"
prefix="$PWD/target/c-library/prefix"
out="$PWD/target/peer/outside"
[ -f target/embree4/lib/libembree4.so ] || scripts/embree4.sh
# The installed library must be this checkout's: reinstall when the header or any loader source is newer.
if [ ! -f "$prefix/lib/libbvhc.so" ] \
  || [ -n "$(find crates/bvhc-loader/src crates/bvhc-capi -newer "$prefix/lib/libbvhc.so" -type f | head -n 1)" ]; then
  PREFIX="$prefix" scripts/install-c-library.sh >/dev/null
fi
mkdir -p "$out"
tables="${PEER_TABLES:-single,batches,in-process}"
for program in embree_peer embree_batches embree_points; do
  cc -O2 -std=c11 -Wall -Wextra -o "$out/$program" "benches/c/$program.c" \
    $(PKG_CONFIG_PATH="$prefix/lib/pkgconfig" pkg-config --cflags --libs bvhc) \
    -L target/embree4/lib -Wl,-rpath,"$PWD/target/embree4/lib" -lembree4 -lm
done
# The benchmark's conversions, triangles and ray sets, written instead of timed.
BVHC_PEER_WRITE="$out" BVHC_PEER_SCENES="$scenes" BVHC_BENCH_RAYS="$rays" BVHC_PEER_CAMERA=512x384 \
  cargo bench --quiet --bench peer --features embree4 >/dev/null
IFS=',' read -ra names <<< "$scenes"
if [[ ",$tables," == *,single,* ]]; then
echo "## From outside: benches/c/embree_peer.c (C API, one call a ray) against Embree's C API"
echo
echo "| scene | rays | query | bvhc | bvhc unchecked | Embree | bvhc / Embree | unchecked / Embree | answered differently |"
echo "|---|---|---|---|---|---|---|---|---|"
for name in "${names[@]}"; do
  stem="${name// /-}"
  for set in incoherent primary; do
    "$out/embree_peer" "$out/$stem.bvh" "$out/$stem-triangles.bin" "$out/$stem-$set.bin" | python3 -c '
import json, sys
for line in sys.stdin:
    r = json.loads(line)
    row = [sys.argv[1], sys.argv[2], r["query"]]
    row += ["%.2f" % r[k] for k in ("bvhc", "bvhc unchecked", "Embree", "ratio", "ratio_unchecked")]
    print("| " + " | ".join(row + [str(r["answered_differently"])]) + " |")
' "$name" "$set"
  done
done
echo
fi
if [[ ",$tables," == *,batches,* ]]; then
echo "## From outside: benches/c/embree_batches.c (C batch calls) against Embree's calls, Mrays/s"
echo
echo "| scene | workload | query | rays | bvhc | bvhc coherent | bvhc columns | Embree 1 | Embree 8 | Embree 8 coherent | best / best | calls differ | answered differently |"
echo "|---|---|---|---|---|---|---|---|---|---|---|---|---|"
for name in "${names[@]}"; do
  stem="${name// /-}"
  "$out/embree_batches" "$out/$stem.bvh" "$out/$stem-triangles.bin" | python3 -c '
import json, sys
for line in sys.stdin:
    r = json.loads(line)
    row = [sys.argv[1], r["workload"], r["query"], str(r["rays"])]
    keys = ("bvhc", "bvhc coherent", "bvhc columns", "Embree 1", "Embree 8", "Embree 8 coherent", "ratio")
    row += ["%.2f" % r[k] if r[k] else "-" for k in keys]
    print("| " + " | ".join(row + [str(r["bvhc_calls_differ"]), str(r["answered_differently"])]) + " |", flush=True)
' "$name"
done
echo
fi
if [[ ",$tables," == *,points,* ]]; then
echo "## From outside: benches/c/embree_points.c (bvhc_closest_points) against rtcPointQuery, one thread"
echo
for name in "${names[@]}"; do
  stem="${name// /-}"
  echo "### $name"
  echo
  "$out/embree_points" "$out/$stem.bvh" "$out/$stem-triangles.bin" "${PEER_POINTS:-200000}"
  echo
done
fi
[[ ",$tables," == *,in-process,* ]] || exit 0
echo "## In process: benches/peer.rs (Rust API, trusting rays) against Embree through FFI"
echo
BVHC_PEER_SCENES="$scenes" BVHC_BENCH_RAYS="$rays" BVHC_PEER_CAMERA=512x384 \
  cargo bench --quiet --bench peer --features embree4 2>/dev/null | grep -v '^$'
