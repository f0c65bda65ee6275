#!/usr/bin/env bash
# tests/gpu/run.sh BUNDLE [TEST_FILTER] — on the GPU machine: installs the
# bundle from tests/gpu/bundle.sh under /opt/vantage-gpu, points its
# binaries at the bundled loader, and runs the tests whose name contains
# TEST_FILTER (default "gl") against the machine's NVIDIA EGL. Prints the
# driver and the GL strings the renderer reports.
set -uo pipefail
src=${1:?usage: run.sh BUNDLE [FILTER]}
filter=${2:-gl}
dst=/opt/vantage-gpu
rm -rf "$dst"; mkdir -p "$dst"; cp -r "$src"/. "$dst"/
# the bundled interpreter, by absolute path (patchelf here, at bundle time,
# would need the path to exist here): run each binary through a wrapper
for b in "$dst"/bin/*; do
  mv "$b" "$b.real"
  printf '#!/bin/sh\nexec %s/lib/ld-linux-x86-64.so.2 --library-path %s/lib:${NVLIB:-/usr/local/nvidia/lib64} %s.real "$@"\n' \
    "$dst" "$dst" "$b" > "$b"
  chmod +x "$b"
done
export NVLIB=/usr/local/nvidia/lib64
[ -d "$NVLIB" ] || NVLIB=/usr/lib/x86_64-linux-gnu
for f in /usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json /usr/share/glvnd/egl_vendor.d/10_nvidia.json; do
  [ -f "$f" ] && export __EGL_VENDOR_LIBRARY_FILENAMES=$f && break
done
echo "EGL vendor: ${__EGL_VENDOR_LIBRARY_FILENAMES:-none found}"
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader || true
VANTAGE_TEST_ONLY=$filter VANTAGE_BIN_DIR=$dst/bin "$dst/bin/vantage_tests"
