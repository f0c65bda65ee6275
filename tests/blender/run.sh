#!/bin/sh
# tests/blender/run.sh — the Blender live-link's tests (client/blender), as
# `make test` and `make test-blender` run them: headless Blender
# (`blender -b --factory-startup --python FILE`) drives the add-on against a
# real vantaged of VANTAGE_BIN_DIR (default build/release), each test file
# with its own daemon (--data-dir and --tokens in a temporary directory),
# and reads the daemon's state back with that build's `vantage` CLI.
# test_codec.py (plain python3: the codec against PROTOCOL.md's tables), then two
# Blender processes; about 12 s in all on an idle 2-core machine.
# Exit status: 0 all passed (or blender is not installed: skipped, said on
# stderr), 1 a test failed, 2 a binary is missing.
set -eu
cd "$(dirname "$0")/../.."
: "${VANTAGE_BIN_DIR:=build/release}"
export VANTAGE_BIN_DIR
for f in "$VANTAGE_BIN_DIR/vantaged" "$VANTAGE_BIN_DIR/vantage" build/vantage_link.zip; do
    [ -e "$f" ] || { echo "tests/blender: $f is missing (make CONFIG=release all)" >&2; exit 2; }
done
# the codec against PROTOCOL.md's tables: plain python3, no Blender needed
python3 tests/blender/test_codec.py || exit 1
if ! command -v blender >/dev/null 2>&1; then
    echo "tests/blender: SKIPPED: blender is not installed (make deps installs it)" >&2
    exit 0
fi
status=0
log=$(mktemp)
scripts=$(mktemp -d)
trap 'rm -rf "$log" "$scripts"' EXIT
# test_errors.py installs the zip as a user does, into a scripts folder of its own
export VANTAGE_ADDON_ZIP="$PWD/build/vantage_link.zip" BLENDER_USER_SCRIPTS="$scripts"
for t in tests/blender/test_link.py tests/blender/test_errors.py; do
    echo "tests/blender: $t"
    rc=0
    blender -b --factory-startup --python-exit-code 1 --python "$t" >"$log" 2>&1 || rc=$?
    # Blender's own start-up lines are noise; the test prints its steps
    grep -v -e '^Blender [34]' -e '^Read prefs' -e '^$' -e '^Blender quit' "$log" || true
    if [ "$rc" -ne 0 ]; then
        echo "tests/blender: $t FAILED (exit $rc)" >&2
        status=1
    fi
done
exit $status
