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
DEST=/opt/vantage-gpu   # where tests/gpu/run.sh installs it on the GPU machine
command -v patchelf >/dev/null || { echo "bundle.sh: needs patchelf (apt-get install patchelf)"; exit 1; }
rm -rf "$out"
mkdir -p "$out/bin" "$out/lib"
# not the CLI: SDL and its libraries are 20 MB the GL tests do not need;
# BUNDLE_BINS names others instead, and then no fuzzers (tests/gpu/bench.sh:
# "bench_render": bench_h264 links libavcodec and its ~150 MB of codecs)
bins=${BUNDLE_BINS:-"vantage_tests vantaged"}
for b in $bins; do cp "$build/$b" "$out/bin/"; done
# libFuzzer builds (make build/fuzz/fuzz_NAME), when there: a GPU machine's
# many cores run a campaign in minutes
for f in fuzz_query fuzz_render fuzz_render_gl; do
  [ -z "${BUNDLE_BINS:-}" ] && [ -x "build/fuzz/$f" ] && cp "build/fuzz/$f" "$out/bin/" || true
done
for b in "$out"/bin/*; do
  ldd "$b" | awk '/=> \//{print $3} /^\t\/lib/{print $1}'
done | sort -u | while read -r l; do cp -L "$l" "$out/lib/"; done
# libglvnd's dispatchers (libepoxy opens libOpenGL or libGL itself); the
# GPU's vendor library is found through __EGL_VENDOR_LIBRARY_FILENAMES there
for l in libOpenGL.so.0 libGL.so.1 libGLX.so.0 libGLdispatch.so.0 libEGL.so.1; do
  cp -L "/lib/x86_64-linux-gnu/$l" "$out/lib/"
done
cp -L /lib64/ld-linux-x86-64.so.2 "$out/lib/"
# debug sections are most of the size (the machine takes 64 MiB in all)
strip --strip-debug "$out"/bin/* "$out"/lib/* 2>/dev/null || true
# the binaries load the bundled loader and libraries from where run.sh puts
# them, also when they start themselves again (libFuzzer's -jobs, the tests'
# vantaged): an interpreter and an RPATH of that absolute path
for b in "$out"/bin/*; do
  patchelf --set-interpreter "$DEST/lib/ld-linux-x86-64.so.2" --force-rpath \
    --set-rpath "$DEST/lib:/usr/local/nvidia/lib64:/usr/lib/x86_64-linux-gnu" "$b"
done
du -sh "$out"
