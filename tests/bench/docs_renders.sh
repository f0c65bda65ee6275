#!/usr/bin/env bash
# docs_renders.sh — the demo city pictures in docs/, rendered by the daemon
# (software renderer, the daemon's own JPEG encoder at quality 85, 1280x720)
# with the environment a fresh city has (the day preset: sun, analytic sky,
# light fog, auto exposure) and the night preset (`vantage env --night`):
#   city_day.jpg          over a crossing and a park, by day
#   city_night.jpg        the same view at night (lamps and windows)
#   city_street.jpg       street level, eye height 1.7 m, down an avenue
#   city_aerial.jpg       the whole city from 250 m, oblique
#   city_topdown.jpg      straight down from 400 m (the commander's view)
#   city_destruction.jpg  a tower with a hole blown in it (vantage destroy,
#                         20 debris entities), from across the street
# Usage: tests/bench/docs_renders.sh [BUILD_DIR] [OUT_DIR] (build/release,
# docs; `make docs-renders`). DOCS_PREVIEW=DIR also writes each view as a
# 640x360 PNG there (for viewers that do not read JPEG).
set -euo pipefail
B=${1:-build/release}
OUT=${2:-docs}
# shellcheck source=tests/bench/vantaged_tmp.sh
. "$(dirname "$0")/vantaged_tmp.sh"
start_daemon docs --scene demo
mkdir -p "$OUT"

shot() { # shot NAME render-options...
    local name=$1
    shift
    V render "$@" --size 1280x720 --quality 85 -o "$OUT/$name.jpg"
    if [ -n "${DOCS_PREVIEW:-}" ]; then
        mkdir -p "$DOCS_PREVIEW"
        V render "$@" --size 640x360 -o "$DOCS_PREVIEW/$name.png" >/dev/null
    fi
}

MID=(--eye "4,30,-60" --at "0,5,20" --fov 60)
V env --day >/dev/null
shot city_day "${MID[@]}"
shot city_street --eye -4,1.7,-128 --at -4,4,0 --fov 60
shot city_aerial --eye 150,250,-250 --at 0,0,0 --fov 60
shot city_topdown --eye 0,400,0 --at 0,0,0 --up 0,0,1 --fov 60
# building 123 of the demo city: a 70 m tower at x -36..-8, z -65..-49,
# its east face on the avenue along x = 0
V destroy 123 -8,9,-57 5 --debris 20 >/dev/null
shot city_destruction --eye 9,4,-80 --at -8,8,-57 --fov 50
V env --night >/dev/null
shot city_night "${MID[@]}"
ls -l "$OUT"/city_*.jpg
