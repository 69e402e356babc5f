#!/usr/bin/env python3
"""Turn operators_bench JSON output into the markdown tables of docs/performance.md.

Usage:
    build/tests/bench/operators_bench --benchmark_format=json > ops.json
    scripts/bench_table.py ops.json [--time cpu|real]

Prints two tables: operator assembly, and the solver phases (analysis, numeric
factorization, one solve, solve/factorization ratio, nnz(L)) per system and
factor kind. Times in ms; CPU time by default (the build machine is shared, so
wall time includes waiting for a core).
"""
import argparse
import json
import re
import sys

NAME = re.compile(r"^(?P<base>BM_\w+)(?:/(?P<system>\w+)/(?P<kind>\w+))?/cells:(?P<cells>\d+)")
TO_MS = {"ns": 1e-6, "us": 1e-3, "ms": 1.0, "s": 1e3}


def load(path, time_key):
    with open(path) as f:
        data = json.load(f)
    rows = {}
    for b in data["benchmarks"]:
        if b.get("run_type", "iteration") != "iteration":
            continue
        m = NAME.match(b["name"])
        if not m:
            continue
        key = (m["base"], m["system"], m["kind"], int(m["cells"]))
        rows[key] = {
            "ms": b[time_key] * TO_MS[b.get("time_unit", "ns")],
            "n": int(b.get("n", 0)),
            "nnzL": int(b.get("nnzL", 0)),
        }
    return data.get("context", {}), rows


def fmt(ms):
    if ms is None:
        return "–"
    return f"{ms:.3f}" if ms < 1 else (f"{ms:.2f}" if ms < 10 else f"{ms:.1f}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("json")
    parser.add_argument("--time", choices=["cpu", "real"], default="cpu")
    args = parser.parse_args()
    context, rows = load(args.json, f"{args.time}_time")
    if not rows:
        sys.exit("no operators_bench results in " + args.json)
    cells = sorted({k[3] for k in rows})
    vertices = {c: (c + 1) ** 2 for c in cells}

    print(f"{args.time.upper()} time in ms; {context.get('num_cpus', '?')} CPUs at "
          f"{context.get('mhz_per_cpu', '?')} MHz, {context.get('date', '')}.\n")

    print("| assembly | " + " | ".join(f"{vertices[c]:,} v" for c in cells) + " |")
    print("|---|" + "---:|" * len(cells))
    for base, label in [("BM_AssembleCotanLaplacian", "cotan Laplacian (from weights)"),
                        ("BM_AssembleAnisotropicStiffness", "anisotropic stiffness L_S"),
                        ("BM_AssembleConnectionLaplacian", "connection Laplacian (complex)")]:
        cols = [fmt(rows.get((base, None, None, c), {}).get("ms")) for c in cells]
        print(f"| {label} | " + " | ".join(cols) + " |")
    print()

    print("| system | kind | vertices | unknowns | nnz(L) | analysis | factorization | solve | solve/factor |")
    print("|---|---|---:|---:|---:|---:|---:|---:|---:|")
    for system in ["Scalar", "Connection", "Connection2N"]:
        for kind in ["Simplicial", "Supernodal"]:
            for c in cells:
                a = rows.get(("BM_Analyze", system, kind, c))
                f = rows.get(("BM_Factorize", system, kind, c))
                s = rows.get(("BM_Solve", system, kind, c))
                if not (a and f and s):
                    continue
                print(f"| {system} | {kind} | {vertices[c]:,} | {f['n']:,} | {f['nnzL']:,} | "
                      f"{fmt(a['ms'])} | {fmt(f['ms'])} | {fmt(s['ms'])} | "
                      f"{s['ms'] / f['ms']:.3f} |")
    share = [rows.get(("BM_ConnectionShareAnalysis", None, None, c)) for c in cells]
    if all(share):
        print()
        print("| connection analysis shared from the scalar solver | "
              + " | ".join(f"{vertices[c]:,} v" for c in cells) + " |")
        print("|---|" + "---:|" * len(cells))
        print("| shareAnalysisFrom (ms) | " + " | ".join(fmt(s["ms"]) for s in share) + " |")


if __name__ == "__main__":
    main()
