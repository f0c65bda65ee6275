#!/usr/bin/env bash
# tests/gpu/bench.sh BUNDLE OUTDIR — on the GPU machine: the frame benches
# on its GPU (a developer's measurement, never part of `make test`). The
# bundle is tests/gpu/bundle.sh's with BUNDLE_BINS="bench_render". Prints
# the GPU, then bench_render's demo city frames (software on 2 threads and
# OpenGL on the GPU, at 1280x720 and 640x360); the same lines go to
# OUTDIR/gpu-bench.txt.
set -uo pipefail
src=${1:?usage: bench.sh BUNDLE OUTDIR}
out=${2:?usage: bench.sh BUNDLE OUTDIR}
dst=/opt/vantage-gpu
rm -rf "$dst"; mkdir -p "$dst" "$out"; cp -r "$src"/. "$dst"/
for f in /usr/local/nvidia/share/glvnd/egl_vendor.d/10_nvidia.json /usr/share/glvnd/egl_vendor.d/10_nvidia.json; do
  [ -f "$f" ] && export __EGL_VENDOR_LIBRARY_FILENAMES=$f && break
done
{
  echo "EGL vendor: ${__EGL_VENDOR_LIBRARY_FILENAMES:-none found}"
  nvidia-smi --query-gpu=name,driver_version --format=csv,noheader || true
  echo "cpus: $(nproc), $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2)"
  for size in 1280x720 640x360; do
    echo "== bench_render --city-only --reps 15 --size $size"
    "$dst/bin/bench_render" --city-only --reps 15 --size $size 2>&1
  done
} 2>&1 | tee "$out/gpu-bench.txt"
