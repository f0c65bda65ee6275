#!/bin/sh
# make_fixture.sh OLD_TREE — rebuilds tests/data/upgrade_v1: a data
# directory written by protocol version 1's vantaged (journal format 1,
# snapshot format 2), which tests/test_upgrade.c opens with today's daemon.
#
# OLD_TREE: a checkout of main at ad84e3d (the last commit before protocol
# version 2), built:
#   git worktree add /tmp/vantage-v1 ad84e3d
#   make -C /tmp/vantage-v1 -j2 CONFIG=release all
#   tests/data/upgrade_v1/make_fixture.sh /tmp/vantage-v1
#   git worktree remove /tmp/vantage-v1
# What it does: builds make_fixture.c against the old tree's libvantage;
# runs the old vantaged (--scene empty --data-dir) with
# VANTAGED_SNAPSHOT_EACH_TURN=1 for part a (so all of it ends in a
# snapshot), stops it (SIGTERM), runs it again without for part b (so all
# of that stays in the journal, in version 1's record layouts), stops it,
# and keeps the snapshot and journal files (not LOCK).
set -eu
old=$(cd "$1" && pwd)
here=$(cd "$(dirname "$0")" && pwd)
bin="$old/build/release"
for f in "$bin/vantaged" "$bin/libvantage.a"; do
    [ -e "$f" ] || { echo "make_fixture.sh: $f is missing: build the old tree first" >&2; exit 2; }
done
git -C "$old" rev-parse HEAD | grep -q '^ad84e3d' || echo "make_fixture.sh: warning: $old is not at ad84e3d" >&2
work=$(mktemp -d)
trap 'kill "$pid" 2>/dev/null || true; rm -rf "$work"' EXIT
pid=
cc -std=c11 -D_GNU_SOURCE -I"$old/client/lib" -I"$old/protocol" -o "$work/make_fixture" "$here/make_fixture.c" \
    "$bin/libvantage.a" -lm -pthread
port=$(( 20000 + $$ % 20000 ))
data="$work/data"

run() { # part, then the daemon's environment
    part=$1
    shift
    env "$@" "$bin/vantaged" --scene empty --port "$port" --data-dir "$data" --durability always \
        --log-level warn --threads 1 &
    pid=$!
    i=0
    until "$work/make_fixture" "$port" "$part" 2>"$work/err"; do
        i=$((i + 1))
        if [ $i -gt 50 ] || ! grep -q "connect\|refused" "$work/err"; then
            cat "$work/err" >&2
            exit 1
        fi
        sleep 0.1
    done
    # part a: let the snapshots of its last turns finish (the daemon checks
    # each turn and every sweep)
    [ "$part" = a ] && sleep 3
    kill -TERM "$pid"
    wait "$pid"
    pid=
}

run a VANTAGED_SNAPSHOT_EACH_TURN=1
run b VANTAGED_SNAPSHOT_EACH_TURN=0
ls "$data"
nsnap=$(ls "$data" | grep -c '^snapshot\.[0-9]*$' || true)
njr=$(ls "$data" | grep -c '^journal\.[0-9]*$' || true)
if [ "$nsnap" != 1 ] || [ "$njr" != 1 ]; then
    echo "make_fixture.sh: expected one snapshot and one journal, got $nsnap and $njr" >&2
    exit 1
fi
jr=$(ls "$data" | grep '^journal\.[0-9]*$')
[ "$(stat -c %s "$data/$jr")" -gt 32 ] || { echo "make_fixture.sh: the journal holds no record" >&2; exit 1; }
rm -f "$here"/snapshot.* "$here"/journal.*
cp "$data"/snapshot.* "$data"/journal.* "$here/"
ls -l "$here"
