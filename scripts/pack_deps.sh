#!/usr/bin/env bash
# Packs the build and test dependencies of difftrans (the Debian 12 packages
# of scripts/install-deps.sh, with the runtime libraries they need, and
# ninja) into one .tar.xz, for a machine that has a compiler, CMake and
# (for the device build) nvcc, but not these packages: copy the archive
# there and run `bash scripts/gpu_check.sh ARCHIVE`, which unpacks it.
#
#   bash scripts/pack_deps.sh [ARCHIVE]   (default: build/deps.tar.xz)
set -euo pipefail
cd "$(dirname "$0")/.."
out=$(realpath -m "${1:-build/deps.tar.xz}")
packages=(
  doctest-dev libbenchmark-dev libbenchmark1debian libcli11-dev libdeflate0 libdeflate-dev libeigen3-dev
  libembree-dev libembree3-3 libglm-dev libimath-3-1-29 libimath-dev libnanoflann-dev libopenexr-3-1-30
  libopenexr-dev libpugixml-dev libpugixml1v5 libstb-dev libstb0 libtbb-dev libtbb12 libtbbbind-2-5
  libtbbmalloc2 libtinygltf-dev libtinygltf2d libtinyobjloader-dev libtinyobjloader2rc10 nlohmann-json3-dev
  libhwloc15
)
staging=$(mktemp -d "${TMPDIR:-/tmp}/difftrans-pack.XXXXXX")
trap 'rm -rf "$staging"' EXIT
( cd "$staging" && apt-get download "${packages[@]}" >"$staging/apt.log" 2>&1 ) ||
  { cat "$staging/apt.log" >&2; echo "pack_deps: apt-get download failed (a Debian 12 machine with its package lists is needed)" >&2; exit 1; }
mkdir -p "$staging/root/bin"
for deb in "$staging"/*.deb; do dpkg -x "$deb" "$staging/root"; done
ninja_bin=$(command -v ninja) || { echo "pack_deps: no ninja here to pack" >&2; exit 1; }
cp "$ninja_bin" "$staging/root/bin/"
mkdir -p "$(dirname "$out")"
tar -C "$staging/root" -cJf "$out" usr bin
echo "pack_deps: ${#packages[@]} packages and ninja in $out ($(du -h "$out" | cut -f1))"
