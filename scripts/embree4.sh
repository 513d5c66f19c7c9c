#!/usr/bin/env bash
# Prepares Embree 4.4 as a benchmark peer (`cargo bench --features embree4`): the built library and its TBB come
# out of the `embreex` 4.4.0 wheel on PyPI (a manylinux build with instance arrays and one instance level), into
# target/embree4/lib with the plain `libembree4.so` name the linker looks for. The benchmarks' FFI
# (benches/common/embree.rs) declares the layouts of Embree 4.4.0's headers (RenderKit/embree, tag v4.4.0,
# include/embree4/), so no header is needed here. Not used by tests or CI.
set -euo pipefail
cd "$(dirname "$0")/.."
out="${BVHC_EMBREE4_DIR:-target/embree4}"
mkdir -p "$out/wheel" "$out/lib"
if ! ls "$out"/wheel/embreex-4.4.0*.whl >/dev/null 2>&1; then
  python3 -m pip download --quiet --no-deps --dest "$out/wheel" "embreex==4.4.0.post1"
fi
rm -rf "$out/unpacked"
python3 -m zipfile -e "$out"/wheel/embreex-4.4.0*.whl "$out/unpacked"
cp "$out"/unpacked/embreex.libs/*.so* "$out/lib/"
library=$(cd "$out/lib" && ls libembree4-*.so.* | head -n 1)
ln -sf "$library" "$out/lib/libembree4.so"
rm -rf "$out/unpacked"
echo "Embree 4 ready in $out/lib ($library); run e.g. cargo bench --bench peer --features embree4"
