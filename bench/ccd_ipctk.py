#!/usr/bin/env python3
"""CCD benchmark: untangle's inclusion-based CCD vs ipctk's Tight Inclusion CCD (Wang et al. 2021).

Runs both, in the same run, on
  * every query of shared/data/ccd-sample-queries (thickness / minimum distance 0, exact truth), and
  * the seeded synthetic thickness queries of `ccd_bench` (planted contacts within the thickness,
    and primitives resting parallel at 1.002-1.1 times the thickness), passed to ipctk as
    `min_distance`,
and prints per group: false positives and false negatives of both, queries per second of both, and
the ratio.

    python3 bench/ccd_ipctk.py [--min-seconds S] [--ipc-max-iterations N] [--shared PATH]

ipctk comes from PyPI and is installed only here, in a virtual environment under target/ccd-venv
(created on first use). ipctk is timed through its Python binding, so its numbers include the
per-call cost of pybind11 and numpy conversion; that cost is measured with a trivial ipctk call and
subtracted in the "ipctk core" column (an estimate of the C++ time). untangle is timed in Rust
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


def read_benchmark_csv(path):
    """Queries of one benchmark CSV file: (8 points as float triples, thickness 0, truth)."""
    rows = []
    for line in path.read_text().splitlines():
        f = line.strip().split(",")
        if len(f) != 7:
            continue
        # int / int is correctly rounded in Python; the values are exactly representable.
        xyz = tuple(int(f[2 * k]) / int(f[2 * k + 1]) for k in range(3))
        rows.append((xyz, f[6].strip() == "1"))
    return [([r[0] for r in rows[i:i + 8]], 0.0, rows[i][1]) for i in range(0, len(rows) - 7, 8)]


def read_synthetic(path):
    """Groups written by `ccd_bench --write-synthetic`: {(scene, kind): [(points, thickness, truth)]}."""
    groups = {}
    key = None
    for line in path.read_text().splitlines():
        if line.startswith("#"):
            _, scene, kind, _ = line.split()
            key = (scene, kind)
            groups[key] = []
            continue
        v = line.split()
        c = [float(x) for x in v[:24]]
        groups[key].append(([tuple(c[3 * i:3 * i + 3]) for i in range(8)], float(v[24]), v[25] == "1"))
    return groups


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

    # Ours first: it also writes the synthetic queries.
    synthetic_file = REPO / "target" / "ccd-synthetic-queries.txt"
    out = subprocess.run(
        ["cargo", "run", "-q", "--release", "-p", "untangle", "--example", "ccd_bench", "--",
         "--json", "--min-seconds", str(min_seconds), "--write-synthetic", str(synthetic_file)],
        cwd=REPO, check=True, capture_output=True, text=True,
        env=dict(os.environ, UNTANGLE_SHARED=str(shared)))
    ours = {(g["scene"], g["kind"]): g for g in json.loads(out.stdout)["groups"]}

    groups = []
    root = shared / "data" / "ccd-sample-queries"
    if root.is_dir():
        for scene in sorted(p for p in root.iterdir() if p.is_dir()):
            for kind in ["vertex-face", "edge-edge"]:
                d = scene / kind
                if not d.is_dir():
                    continue
                qs = []
                for f in sorted(d.glob("*.csv")):
                    qs.extend(read_benchmark_csv(f))
                groups.append((scene.name, kind, qs))
    else:
        print(f"note: no CCD benchmark queries at {root}; synthetic groups only")
    for (scene, kind), qs in read_synthetic(synthetic_file).items():
        groups.append((scene, kind, qs))

    # Per-call overhead of the binding: a trivial ipctk function with 8 vector arguments.
    pts = [np.zeros(3) for _ in range(8)]
    n = 20000
    t0 = time.perf_counter()
    for _ in range(n):
        ipctk.point_triangle_aabb_ccd(*pts[:4], *pts[4:], 0.0)
    overhead = (time.perf_counter() - t0) / n

    ti = ipctk.tight_inclusion
    ipc = {}
    for scene, kind, qs in groups:
        fn = ti.point_triangle_ccd if kind == "vertex-face" else ti.edge_edge_ccd
        calls = [([np.array(p, dtype=np.float64) for p in pts], h) for pts, h, _ in qs]
        # Timed passes; the first one also records the answers. Further passes only while the
        # time budget lasts (hard groups take minutes per pass with ipctk's default settings).
        budget = min_seconds / len(groups)
        passes = 0
        t0 = time.perf_counter()
        hits = [fn(*a, min_distance=h, max_iterations=max_iterations)[0] for a, h in calls]
        passes += 1
        while time.perf_counter() - t0 < budget:
            for a, h in calls:
                fn(*a, min_distance=h, max_iterations=max_iterations)
            passes += 1
        secs = (time.perf_counter() - t0) / passes
        fp = sum(1 for hit, (_, _, t) in zip(hits, qs) if hit and not t)
        fneg = sum(1 for hit, (_, _, t) in zip(hits, qs) if t and not hit)
        print(f"  ipctk {scene} {kind}: {len(qs)} queries, {secs:.3f} s per pass", file=sys.stderr, flush=True)
        ipc[(scene, kind)] = dict(queries=len(qs), positives=sum(t for _, _, t in qs), fp=fp, fn=fneg, seconds=secs)

    print(f"ipctk {getattr(ipctk, '__version__', '?')} tight_inclusion (tolerance 1e-6, max_iterations "
          f"{max_iterations:g}, breadth-first); ipctk call overhead {overhead * 1e6:.2f} us/call")
    hdr = (f"{'scene':<28} {'kind':<11} {'n':>5} {'pos':>4} | {'FP ours':>7} {'FN ours':>7} {'FP ipc':>6} "
           f"{'FN ipc':>6} | {'ours q/s':>10} {'ipctk q/s':>10} {'core q/s':>10} | {'ratio':>7} {'core':>7}")

    def line(name, kind, n, pos, fpo, fno, fpi, fni, so, si):
        core = max(si - n * overhead, 1e-12)
        qo, qi, qc = n / so, n / si, n / core
        return (f"{name:<28} {kind:<11} {n:>5} {pos:>4} | {fpo:>7} {fno:>7} {fpi:>6} {fni:>6} | "
                f"{qo:>10.0f} {qi:>10.0f} {qc:>10.0f} | {qo / qi:>7.1f} {qo / qc:>7.1f}")

    for title, pick in [("Wang et al. 2021 benchmark sample, thickness 0", lambda s: not s.startswith("synthetic")),
                        ("synthetic queries with a thickness (min_distance)", lambda s: s.startswith("synthetic"))]:
        rows = [(s, k, qs) for s, k, qs in groups if pick(s)]
        if not rows:
            continue
        print(f"\n{title}")
        print(hdr)
        print("-" * len(hdr))
        tot = [0, 0, 0, 0, 0, 0, 0.0, 0.0]
        for scene, kind, qs in rows:
            i, o = ipc[(scene, kind)], ours[(scene, kind)]
            vals = [i["queries"], i["positives"], o["false_positives"], o["false_negatives"], i["fp"], i["fn"],
                    o["seconds"], i["seconds"]]
            print(line(scene, kind, *vals))
            tot = [a + b for a, b in zip(tot, vals)]
        print("-" * len(hdr))
        print(line("total", "", *tot))


if __name__ == "__main__":
    main()
