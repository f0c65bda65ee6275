#!/bin/sh
# tests/web/run.sh — the browser client's tests (web/js/vproto.js), as
# `make test` and `make test-web` run them: Node's own test runner over
# tests/web/*.test.mjs. Each test file starts its own vantaged of
# VANTAGE_BIN_DIR (default build/release) on a free loopback port (and
# --web on another) with a temporary --data-dir and --tokens file, drives it
# with vproto.js over TCP and the WebSocket and with that build's `vantage`
# CLI, and stops it (SIGTERM, a clean exit checked).
# About 3 s in all on an idle 2-core machine. Exit status: node's (0 all
# passed), 2 when a binary or Node is missing.
set -eu
cd "$(dirname "$0")/../.."
: "${VANTAGE_BIN_DIR:=build/release}"
export VANTAGE_BIN_DIR
for b in vantaged vantage; do
    if [ ! -x "$VANTAGE_BIN_DIR/$b" ]; then
        echo "tests/web: $VANTAGE_BIN_DIR/$b is missing (make CONFIG=release all, or set VANTAGE_BIN_DIR)" >&2
        exit 2
    fi
done
if ! command -v node >/dev/null 2>&1; then
    echo "tests/web: node is missing (make deps installs nodejs)" >&2
    exit 2
fi
# node:test with before/after hooks and a directory argument: Node 18.8 on
# (verified on Node 20)
major=$(node -p 'process.versions.node.split(".")[0]')
if [ "$major" -lt 18 ]; then
    echo "tests/web: node $(node --version) is too old; 18 or later is needed" >&2
    exit 2
fi
# a hung test fails after 30 s instead of stalling make test (Node 20.11 on)
flags=
help=$(node --help)
case "$help" in *--test-timeout*) flags="--test-timeout=30000" ;; esac
# the WebSocket client websocket.test.mjs uses: global in Node 22, behind
# this flag in Node 20 (the test files' processes inherit it)
if ! node -e 'process.exit(typeof WebSocket === "function" ? 0 : 1)'; then
    case "$help" in *--experimental-websocket*) flags="$flags --experimental-websocket" ;; esac
fi
exec node --test $flags tests/web/
