#!/usr/bin/env bash
# tests/gpu/bundle.sh BUILD_DIR OUT_DIR — packs this build's binaries with
# every shared library they load (Debian's glibc and loader included) into
# OUT_DIR, so the OpenGL tests can run on a machine with a real GPU whose
# system is not Debian 12 and that can install nothing (the device machines
# some sessions are lent). tests/gpu/run.sh runs them there. A developer's
# check, never part of `make test`: CI has no GPU.
set -euo pipefail
build=${1:?usage: bundle.sh BUILD_DIR OUT_DIR}
out=${2:?usage: bundle.sh BUILD_DIR OUT_DIR}
rm -rf "$out"
mkdir -p "$out/bin" "$out/lib"
bins="vantage_tests vantaged vantage"
for b in $bins; do cp "$build/$b" "$out/bin/"; done
[ -x "$build/fuzz_render_replay" ] && cp "$build/fuzz_render_replay" "$out/bin/" || true
for b in "$out"/bin/*; do
  ldd "$b" | awk '/=> \//{print $3} /^\t\/lib/{print $1}'
done | sort -u | while read -r l; do cp -L "$l" "$out/lib/"; done
# libglvnd's EGL and dispatch stay: the GPU's vendor library is found
# through __EGL_VENDOR_LIBRARY_FILENAMES there
cp -L /lib64/ld-linux-x86-64.so.2 "$out/lib/"
du -sh "$out"
