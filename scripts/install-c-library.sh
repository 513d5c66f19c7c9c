#!/usr/bin/env bash
# Builds and installs libbvhc, the C library of the loader (crates/bvhc-capi), as a C user expects it:
#
#   PREFIX=/usr/local scripts/install-c-library.sh        # or PREFIX=$HOME/.local, DESTDIR=... for packagers
#
# installs
#   $PREFIX/include/bvhc.h
#   $PREFIX/lib/libbvhc.so.0.1.0, libbvhc.so.0.1 (its SONAME) and libbvhc.so (links), libbvhc.a
#   $PREFIX/lib/pkgconfig/bvhc.pc                  cc app.c $(pkg-config --cflags --libs bvhc) (with an rpath)
#   $PREFIX/lib/cmake/bvhc/bvhcConfig.cmake        find_package(bvhc) ... target_link_libraries(app bvhc::bvhc)
#   $PREFIX/lib/cmake/bvhc/bvhcConfigVersion.cmake (bvhc::bvhc_static for the static library)
#
# The library is built in its own target directory (target/c-library), with the C API crate alone selected,
# so it has the C API's own features whatever the workspace builds: no GPU (wgpu, naga) code in it. Debug
# information is stripped unless STRIP=0. Environment: PREFIX (default /usr/local), DESTDIR (staging root,
# default empty), LIBDIR (default lib), CARGO (default cargo), STRIP (default 1). Under a prefix other than
# /usr or /usr/local it ends by printing the PKG_CONFIG_PATH, CMAKE_PREFIX_PATH and LD_LIBRARY_PATH lines to set.
set -euo pipefail
cd "$(dirname "$0")/.."

prefix="${PREFIX:-/usr/local}"
destdir="${DESTDIR:-}"
libdir_name="${LIBDIR:-lib}"
cargo="${CARGO:-cargo}"
case "$prefix" in
  /*) ;;
  *) echo "install-c-library: PREFIX must be an absolute path (got '$prefix')" >&2; exit 2 ;;
esac

version=$(sed -n 's/^version = "\(.*\)"/\1/p' crates/bvhc-capi/Cargo.toml | head -1)
major=${version%%.*}
rest=${version#*.}
minor=${rest%%.*}
if [ "$major" = 0 ]; then abi="0.$minor"; else abi="$major"; fi

target_dir=target/c-library
"$cargo" build --release --quiet -p bvhc-capi --target-dir "$target_dir"
built="$target_dir/release"

lib="$destdir$prefix/$libdir_name"
include="$destdir$prefix/include"
mkdir -p "$lib/pkgconfig" "$lib/cmake/bvhc" "$include"

install -m 644 crates/bvhc-capi/include/bvhc.h "$include/bvhc.h"
install -m 755 "$built/libbvhc_capi.so" "$lib/libbvhc.so.$version"
install -m 644 "$built/libbvhc_capi.a" "$lib/libbvhc.a"
if [ "${STRIP:-1}" != 0 ] && command -v strip >/dev/null 2>&1; then
  strip --strip-debug "$lib/libbvhc.so.$version" "$lib/libbvhc.a"
fi
ln -sf "libbvhc.so.$version" "$lib/libbvhc.so.$abi"
ln -sf "libbvhc.so.$abi" "$lib/libbvhc.so"

cat > "$lib/pkgconfig/bvhc.pc" <<EOF
prefix=$prefix
libdir=\${prefix}/$libdir_name
includedir=\${prefix}/include

Name: bvhc
Description: Load, verify and trace bvhc's .bvh files (bounding volume hierarchies) from C
Version: $version
Libs: -L\${libdir} -Wl,-rpath,\${libdir} -lbvhc
Libs.private: -lpthread -ldl -lm
Cflags: -I\${includedir}
EOF

cat > "$lib/cmake/bvhc/bvhcConfig.cmake" <<EOF
# bvhc $version: imported targets bvhc::bvhc (shared) and bvhc::bvhc_static.
get_filename_component(_bvhc_prefix "\${CMAKE_CURRENT_LIST_DIR}/../../.." ABSOLUTE)
if(NOT TARGET bvhc::bvhc)
  add_library(bvhc::bvhc SHARED IMPORTED)
  set_target_properties(bvhc::bvhc PROPERTIES
    IMPORTED_LOCATION "\${_bvhc_prefix}/$libdir_name/libbvhc.so.$version"
    IMPORTED_SONAME "libbvhc.so.$abi"
    INTERFACE_INCLUDE_DIRECTORIES "\${_bvhc_prefix}/include")
endif()
if(NOT TARGET bvhc::bvhc_static)
  add_library(bvhc::bvhc_static STATIC IMPORTED)
  set_target_properties(bvhc::bvhc_static PROPERTIES
    IMPORTED_LOCATION "\${_bvhc_prefix}/$libdir_name/libbvhc.a"
    INTERFACE_INCLUDE_DIRECTORIES "\${_bvhc_prefix}/include"
    INTERFACE_LINK_LIBRARIES "pthread;dl;m")
endif()
unset(_bvhc_prefix)
set(bvhc_VERSION $version)
EOF

cat > "$lib/cmake/bvhc/bvhcConfigVersion.cmake" <<EOF
# bvhc $version: a request is compatible when its version is not newer and has the same ABI ($abi).
set(PACKAGE_VERSION $version)
if(PACKAGE_FIND_VERSION VERSION_GREATER PACKAGE_VERSION)
  set(PACKAGE_VERSION_COMPATIBLE FALSE)
elseif("$major" STREQUAL "0" AND NOT PACKAGE_FIND_VERSION_MINOR EQUAL $minor)
  set(PACKAGE_VERSION_COMPATIBLE FALSE)
elseif(NOT "$major" STREQUAL "0" AND NOT PACKAGE_FIND_VERSION_MAJOR EQUAL $major)
  set(PACKAGE_VERSION_COMPATIBLE FALSE)
else()
  set(PACKAGE_VERSION_COMPATIBLE TRUE)
  if(PACKAGE_FIND_VERSION VERSION_EQUAL PACKAGE_VERSION)
    set(PACKAGE_VERSION_EXACT TRUE)
  endif()
endif()
EOF

echo "installed libbvhc $version (ABI $abi) under $destdir$prefix: $(du -h "$lib/libbvhc.so.$version" | cut -f1) shared, $(du -h "$lib/libbvhc.a" | cut -f1) static"
# Outside the prefixes the tools search by default, say what to set (programs linked through pkg-config run
# without more: bvhc.pc carries an rpath to $prefix/$libdir_name; CMake builds keep their own rpaths).
case "$prefix" in
  /usr | /usr/local) ;;
  *)
    echo "to build against it from $prefix:"
    echo "  export PKG_CONFIG_PATH=\"$prefix/$libdir_name/pkgconfig\${PKG_CONFIG_PATH:+:\$PKG_CONFIG_PATH}\""
    echo "  export CMAKE_PREFIX_PATH=\"$prefix\${CMAKE_PREFIX_PATH:+:\$CMAKE_PREFIX_PATH}\""
    echo "  # programs linked otherwise find libbvhc.so at run time with:"
    echo "  export LD_LIBRARY_PATH=\"$prefix/$libdir_name\${LD_LIBRARY_PATH:+:\$LD_LIBRARY_PATH}\""
    ;;
esac
