#!/usr/bin/env bash
# bench_cycles.sh — the renderer against Blender Cycles (issue 20's
# Reference): for each scene a fresh vantaged (empty or the demo city, a
# temporary data dir, a Unix socket in a temporary directory) is loaded
# with the vantage CLI (import, material put, add, env), renders the
# camera (`vantage render`: EXR, linear and exposed, and PNG), and exports
# the scene (`vantage export scene.glb`); Blender 3.4 renders the GLB with
# Cycles on the CPU from the same camera, sun, sky, ground and exposure
# (cycles_render.py says how the units map), twice with two seeds; then
# compare.py prints SSIM and the luminance differences per scene and
# writes OUT/SCENE/side_by_side.png (vantage | cycles | difference).
#
# Usage: tests/bench/cycles/bench_cycles.sh [BUILD_DIR] [OUT_DIR]
#   (defaults build/release, build/bench-cycles; `make bench-cycles`)
# Environment: CYCLES_SAMPLES (128), CYCLES_SIZE (480x270), CYCLES_SCENES
#   ("boxes textured city"), BLENDER (blender), CYCLES_THREADS (2).
# Takes minutes (Cycles at 128 samples, two seeds, three scenes, 2 cores).
set -euo pipefail
B=${1:-build/release}
OUT=${2:-build/bench-cycles}
SAMPLES=${CYCLES_SAMPLES:-128}
SIZE=${CYCLES_SIZE:-480x270}
SCENES=${CYCLES_SCENES:-boxes textured city}
BLENDER=${BLENDER:-blender}
THREADS=${CYCLES_THREADS:-2}
HERE=$(cd "$(dirname "$0")" && pwd)
# numpy: Debian's python3 (the one Blender uses), not a pyenv shim without it
PY=/usr/bin/python3
[ -x $PY ] && $PY -c 'import numpy' 2>/dev/null || PY=python3
$PY -c 'import numpy' || { echo "bench_cycles.sh: compare.py needs numpy (apt-get install python3-numpy)"; exit 1; }
# the comparison tool first checks itself (SSIM against its references)
$PY "$HERE/compare.py" --self-check | tail -1
command -v "$BLENDER" >/dev/null || { echo "bench_cycles.sh: no $BLENDER (apt-get install blender)"; exit 1; }
# shellcheck source=tests/bench/vantaged_tmp.sh
. "$HERE/../vantaged_tmp.sh"
mkdir -p "$OUT"

# The environment both renderers get: set on the daemon here and passed
# to Blender as the same numbers (SUN = azimuth,elevation,lux; SKY =
# color:R,G,B in cd/m^2 or analytic:TURBIDITY; GROUND = height,R,G,B).
env_set() {
    local sky_args
    case $SKY in
    color:*) sky_args=(--sky "$SKY" --sky-intensity 1) ;;
    analytic:*) sky_args=(--sky analytic --turbidity "${SKY#analytic:}" --sky-intensity 1) ;;
    esac
    IFS=, read -r gh gr gg gb <<<"$GROUND"
    V env --sun "$SUN" --sun-color "$SUN_COLOR" "${sky_args[@]}" --ground "$gh" --ground-color "$gr,$gg,$gb" \
        --ground-material 0 --fog 0 --exposure "$EV" >"$ROOT/env.txt"
}

scene_boxes() {
    # boxes and spheres of five materials (diffuse, plastic, gold, glossy,
    # rough) on a grey ground, the sun at 50 degrees, the analytic sky
    start_daemon boxes --scene empty
    $PY "$HERE/scenes.py" boxes "$ROOT/boxes.gltf"
    V import "$ROOT/boxes.gltf" >/dev/null
    # one more through the CLI: a semi-gloss white cube (mesh class 1 is
    # the import's first mesh, the unit box)
    V material put 50 --base 0.9,0.9,0.9 --metallic 0 --roughness 0.5 >/dev/null
    V add 9001 --mesh 1 --pos -7,0.6,4 --rotate 30,0,0 --scale 1.2 --material 50 >/dev/null
    SUN=225,50,100000 SUN_COLOR=1,1,1 SKY=analytic:2.5 GROUND=0,0.25,0.25,0.25 EV=15
    EYE=10,7,13 AT=-0.5,1,0 FOV=45
}

scene_textured() {
    # brick walls (an sRGB base-colour texture, mipmapped) on a concrete
    # slab under a uniform blue-grey sky and a low sun from the south-east
    start_daemon textured --scene empty
    $PY "$HERE/scenes.py" textured "$ROOT/textured.gltf"
    V import "$ROOT/textured.gltf" >/dev/null
    SUN=150,35,80000 SUN_COLOR=1,0.95,0.88 SKY=color:2500,3200,4500 GROUND=0,0.3,0.3,0.3 EV=14.5
    EYE=4,3.5,11 AT=0,1.5,0 FOV=50
}

scene_city() {
    # a corner of the demo city by day (300 cars): buildings with textured
    # facades, pavements, roofs, trees, lamps, the day preset's sun
    start_daemon city --scene demo --props 300
    SUN=225,50,100000 SUN_COLOR=1,0.96,0.9 SKY=analytic:2.5 GROUND=0,0.08,0.08,0.085 EV=15
    EYE=4,30,-60 AT=0,5,20 FOV=60
}

for s in $SCENES; do
    d="$OUT/$s"
    mkdir -p "$d"
    echo "== $s"
    "scene_$s"
    env_set
    cam=(--eye "$EYE" --at "$AT" --fov "$FOV" --near 0.1 --far 10000 --size "$SIZE")
    V render "${cam[@]}" -o "$d/vantage.exr"
    V render "${cam[@]}" -o "$d/vantage.png"
    V export "$d/scene.glb"
    stop_daemon
    for seed in 1 2; do
        name=$([ $seed = 1 ] && echo cycles || echo cycles_b)
        t0=$(date +%s)
        "$BLENDER" -b --factory-startup --python "$HERE/cycles_render.py" -- --glb "$d/scene.glb" \
            --eye "$EYE" --at "$AT" --fov "$FOV" --near 0.1 --far 10000 --size "$SIZE" --sun "$SUN" \
            --sun-color "$SUN_COLOR" --sky "$SKY" --ground "$GROUND" --ev "$EV" --samples "$SAMPLES" \
            --threads "$THREADS" --seed "$seed" --name "$name" --out "$d" \
            --vantage-exr "$d/vantage.exr" --vantage-png "$d/vantage.png" >"$d/blender_$seed.log" 2>&1 ||
            { tail -20 "$d/blender_$seed.log"; exit 1; }
        grep '^cycles_render.py:' "$d/blender_$seed.log" | sed "s/\$/ ($(($(date +%s) - t0)) s with the import)/"
    done
done
echo "== $("$BLENDER" --version 2>/dev/null | head -1), Cycles CPU, $SAMPLES samples, $SIZE, no denoiser; $(nproc) cores"
# shellcheck disable=SC2046
$PY "$HERE/compare.py" $(for s in $SCENES; do echo "$OUT/$s"; done)
echo "pictures: $OUT/*/side_by_side.png (vantage | cycles | 4 x |display luma difference|)"
