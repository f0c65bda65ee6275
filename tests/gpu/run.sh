#!/usr/bin/env bash
# tests/gpu/run.sh BUNDLE [TEST_FILTER...] — on the GPU machine: installs the
# bundle from tests/gpu/bundle.sh at /opt/vantage-gpu (where its binaries
# look for their loader and libraries), finds the machine's NVIDIA EGL
# vendor library, and runs the tests whose names contain each TEST_FILTER
# (default: gl). Prints the GPU and driver.
set -uo pipefail
src=${1:?usage: run.sh BUNDLE [FILTER...]}
shift
dst=/opt/vantage-gpu
rm -rf "$dst"; mkdir -p "$dst"; cp -r "$src"/. "$dst"/
# no LD_LIBRARY_PATH: the machine's own tools need its newer glibc; the
# bundled binaries find theirs (and the driver's) through their RPATH
for f in /usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json /usr/share/glvnd/egl_vendor.d/10_nvidia.json; do
  [ -f "$f" ] && export __EGL_VENDOR_LIBRARY_FILENAMES=$f && break
done
echo "EGL vendor: ${__EGL_VENDOR_LIBRARY_FILENAMES:-none found}"
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader || true
rc=0
for filter in "${@:-gl}"; do
  VANTAGE_TEST_ONLY=$filter VANTAGE_BIN_DIR=$dst/bin "$dst/bin/vantage_tests" || rc=1
done
exit $rc
