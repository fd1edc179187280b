#!/usr/bin/env python3
"""CCD benchmark: untangle's inclusion-based CCD vs ipctk's Tight Inclusion CCD (Wang et al. 2021).

Runs both on every query of shared/data/ccd-sample-queries (thickness / minimum distance 0) in the
same run and prints, per scene and kind, false positives and false negatives of both, queries per
second of both and the ratio.

    python3 bench/ccd_ipctk.py [--min-seconds S] [--ipc-max-iterations N] [--shared PATH]

ipctk comes from PyPI and is installed only here, in a virtual environment under
target/ccd-venv (created on first use). ipctk is timed through its Python binding, so its numbers
include the per-call cost of pybind11 (measured separately with a trivial ipctk call and reported as
"ipctk call overhead"; the "ipctk core" column subtracts it). untangle is timed in Rust
(`cargo run --release -p untangle --example ccd_bench -- --json`), single-threaded.
"""
import json
import os
import subprocess
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
VENV = REPO / "target" / "ccd-venv"


def ensure_venv():
    """Re-executes this script inside a venv that has ipctk and numpy."""
    py = VENV / "bin" / "python"
    if Path(sys.prefix).resolve() == VENV.resolve():
        return
    if not py.exists():
        subprocess.check_call([sys.executable, "-m", "venv", str(VENV)])
    try:
        subprocess.check_call([str(py), "-c", "import ipctk, numpy"], stderr=subprocess.DEVNULL)
    except subprocess.CalledProcessError:
        subprocess.check_call([str(py), "-m", "pip", "install", "-q", "ipctk", "numpy"])
    os.execv(str(py), [str(py)] + sys.argv)


def read_queries(path):
    """Queries of one CSV file: (list of 8 points as float triples, truth)."""
    rows = []
    for line in path.read_text().splitlines():
        f = line.strip().split(",")
        if len(f) != 7:
            continue
        # int / int is correctly rounded in Python; the values are exactly representable.
        xyz = tuple(int(f[2 * k]) / int(f[2 * k + 1]) for k in range(3))
        rows.append((xyz, f[6].strip() == "1"))
    return [([r[0] for r in rows[i:i + 8]], rows[i][1]) for i in range(0, len(rows) - 7, 8)]


def main():
    ensure_venv()
    import numpy as np
    import ipctk

    args = sys.argv[1:]
    min_seconds = float(args[args.index("--min-seconds") + 1]) if "--min-seconds" in args else 1.0
    # ipctk's default (1e7); lower values trade false positives for speed.
    max_iterations = int(float(args[args.index("--ipc-max-iterations") + 1])) if "--ipc-max-iterations" in args else 10_000_000
    shared = Path(args[args.index("--shared") + 1]) if "--shared" in args else Path(
        os.environ.get("UNTANGLE_SHARED", REPO.parent / "shared"))
    root = shared / "data" / "ccd-sample-queries"
    if not root.is_dir():
        print(f"skipping: no CCD queries at {root}")
        return

    ti = ipctk.tight_inclusion
    groups = []
    for scene in sorted(p for p in root.iterdir() if p.is_dir()):
        for kind in ["vertex-face", "edge-edge"]:
            d = scene / kind
            if not d.is_dir():
                continue
            qs = []
            for f in sorted(d.glob("*.csv")):
                qs.extend(read_queries(f))
            groups.append((scene.name, kind, qs))

    # Per-call overhead of the binding: a trivial ipctk function with 8 vector arguments.
    pts = [np.zeros(3) for _ in range(8)]
    n = 20000
    t0 = time.perf_counter()
    for _ in range(n):
        ipctk.point_triangle_aabb_ccd(*pts[:4], *pts[4:], 0.0)
    overhead = (time.perf_counter() - t0) / n

    ipc = {}
    for scene, kind, qs in groups:
        fn = ti.point_triangle_ccd if kind == "vertex-face" else ti.edge_edge_ccd
        arrs = [[np.array(p, dtype=np.float64) for p in pts] for pts, _ in qs]
        # Timed passes; the first one also records the answers. Further passes only while the
        # time budget lasts (hard groups take minutes per pass with ipctk's default settings).
        budget = min_seconds / len(groups)
        passes = 0
        t0 = time.perf_counter()
        hits = [fn(*a, max_iterations=max_iterations)[0] for a in arrs]
        passes += 1
        while time.perf_counter() - t0 < budget:
            for a in arrs:
                fn(*a, max_iterations=max_iterations)
            passes += 1
        secs = (time.perf_counter() - t0) / passes
        fp = sum(1 for h, (_, t) in zip(hits, qs) if h and not t)
        fneg = sum(1 for h, (_, t) in zip(hits, qs) if t and not h)
        print(f"  ipctk {scene} {kind}: {len(qs)} queries in {secs:.3f} s per pass", file=sys.stderr, flush=True)
        ipc[(scene, kind)] = dict(queries=len(qs), positives=sum(t for _, t in qs), fp=fp, fn=fneg, seconds=secs)

    out = subprocess.run(
        ["cargo", "run", "-q", "--release", "-p", "untangle", "--example", "ccd_bench", "--",
         "--json", "--min-seconds", str(min_seconds)],
        cwd=REPO, check=True, capture_output=True, text=True,
        env=dict(os.environ, UNTANGLE_SHARED=str(shared)))
    ours = {(g["scene"], g["kind"]): g for g in json.loads(out.stdout)["groups"]}

    print(f"ipctk {getattr(ipctk, '__version__', '?')} tight_inclusion (tolerance 1e-6, max_iterations "
          f"{max_iterations:g}, breadth-first); ipctk call overhead {overhead * 1e6:.2f} us/call")
    hdr = (f"{'scene':<28} {'kind':<11} {'n':>5} {'pos':>4} | {'FP ours':>7} {'FN ours':>7} {'FP ipc':>6} "
           f"{'FN ipc':>6} | {'ours q/s':>10} {'ipctk q/s':>10} {'core q/s':>10} | {'ratio':>6} {'core':>6}")
    print(hdr)
    print("-" * len(hdr))
    tot = dict(n=0, fpo=0, fno=0, fpi=0, fni=0, so=0.0, si=0.0)
    for scene, kind, qs in groups:
        i, o = ipc[(scene, kind)], ours[(scene, kind)]
        n = i["queries"]
        core = max(i["seconds"] - n * overhead, 1e-12)
        qo, qi, qc = n / o["seconds"], n / i["seconds"], n / core
        print(f"{scene:<28} {kind:<11} {n:>5} {i['positives']:>4} | {o['false_positives']:>7} "
              f"{o['false_negatives']:>7} {i['fp']:>6} {i['fn']:>6} | {qo:>10.0f} {qi:>10.0f} {qc:>10.0f} | "
              f"{qo / qi:>6.1f} {qo / qc:>6.1f}")
        tot["n"] += n
        tot["fpo"] += o["false_positives"]
        tot["fno"] += o["false_negatives"]
        tot["fpi"] += i["fp"]
        tot["fni"] += i["fn"]
        tot["so"] += o["seconds"]
        tot["si"] += i["seconds"]
    core = tot["si"] - tot["n"] * overhead
    qo, qi, qc = tot["n"] / tot["so"], tot["n"] / tot["si"], tot["n"] / core
    print("-" * len(hdr))
    print(f"{'total':<28} {'':<11} {tot['n']:>5} {'':>4} | {tot['fpo']:>7} {tot['fno']:>7} {tot['fpi']:>6} "
          f"{tot['fni']:>6} | {qo:>10.0f} {qi:>10.0f} {qc:>10.0f} | {qo / qi:>6.1f} {qo / qc:>6.1f}")


if __name__ == "__main__":
    main()
