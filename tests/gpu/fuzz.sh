#!/usr/bin/env bash
# tests/gpu/fuzz.sh TARGET SECONDS JOBS OUTDIR — after run.sh installed the
# bundle: a libFuzzer campaign of the bundled fuzz_TARGET on a copy of
# tests/fuzz/corpus/TARGET, JOBS processes for SECONDS each. Writes to
# OUTDIR the summed executions, the workers' logs' last lines, any crash
# inputs, and the grown corpus (TARGET-corpus.tar.gz) for `make fuzz-merge`.
set -uo pipefail
t=${1:?target}; secs=${2:?seconds}; jobs=${3:?jobs}; out=${4:?outdir}
dst=/opt/vantage-gpu
work=/tmp/fuzz-$t; rm -rf "$work"; mkdir -p "$work/corpus" "$out"
cp tests/fuzz/corpus/$t/* "$work/corpus/" 2>/dev/null
cd "$work"
"$dst/bin/fuzz_$t" -jobs=$jobs -workers=$jobs -max_total_time=$secs -max_len=1024 -print_final_stats=1 \
  -artifact_prefix="$out/crash-$t-" corpus > /dev/null 2>&1
runs=$(cat fuzz-*.log | awk '/stat::number_of_executed_units/ {s += $2} END {print s + 0}')
crashes=$(ls "$out"/crash-$t-* 2>/dev/null | wc -l)
cov=$(grep -h "cov:" fuzz-*.log | tail -1)
echo "fuzz $t: $jobs jobs x $secs s: $runs executions, $crashes crash inputs; corpus $(ls corpus | wc -l) files; last: $cov" | tee -a "$out/fuzz-summary.txt"
tail -n 3 fuzz-*.log > "$out/$t-logs.txt" 2>&1
tar czf "$out/$t-corpus.tar.gz" corpus
