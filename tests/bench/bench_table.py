#!/usr/bin/env python3
"""bench_table.py — turns `bench_cull --json` lines into the Markdown tables
of BENCHMARKS.md:  build/release/bench_cull --json | tests/bench/bench_table.py"""
import json
import sys

rows = [json.loads(l) for l in sys.stdin if l.startswith("{")]


def us(ns):
    return f"{ns / 1000:.1f}" if ns < 1e7 else f"{ns / 1e6:.1f} ms"


def table(title, select, cols):
    sel = [r for r in rows if select(r)]
    if not sel:
        return
    print(f"\n### {title}\n")
    print("| " + " | ".join(c[0] for c in cols) + " |")
    print("|" + "---|" * len(cols))
    for r in sel:
        print("| " + " | ".join(str(c[1](r)) for c in cols) + " |")


base = [r for r in rows if r["bench"] == "naive"]
cols = [
    ("entities", lambda r: r["entities"]),
    ("views", lambda r: r["views"]),
    ("threads", lambda r: r["threads"]),
    ("isa", lambda r: r["isa"]),
    ("stage", lambda r: r["stage"]),
    ("cache", lambda r: r["cache"]),
    ("median µs", lambda r: us(r["median_ns"])),
    ("min µs", lambda r: us(r["min_ns"])),
    ("visible", lambda r: f"{r['visible']:.0f}"),
    ("tested", lambda r: r.get("tested", "")),
]
for n in sorted({r["entities"] for r in rows}):
    table(f"{n:,} entities: naive early-out baseline", lambda r, n=n: r["bench"] == "naive" and r["entities"] == n, cols)
    for scene in ("grid", "flat"):
        table(f"{n:,} entities, {scene}", lambda r, n=n, s=scene: r["bench"] == "cull" and r["entities"] == n and r["scene"] == s, cols)
