#!/usr/bin/env python3
"""Side-by-side benchmark: untangle's full intersection analysis vs MeshLab's per-face
self-intersection selection (pymeshlab), on the same scenes, in the same run.

Usage (from the repository root):  python3 bench/analysis_vs_meshlab.py [--runs N]

Installs pymeshlab into target/bench-venv (benchmark only; never a test dependency), builds the
release binary, writes the scenes with `untangle scene`, then times:
  - untangle: `untangle check --json`, the report's timing_ms.total (broad phase + crossings +
    paths + kinds + regions + colouring), minimum and median over N runs (warm worker pool);
  - MeshLab: compute_selection_by_self_intersections_per_face (detection only), min and median.
It also cross-checks the number of intersecting faces: MeshLab's selection must equal our
`intersecting_triangles` on generic scenes (where no triangle merely touches another)."""
import json, os, statistics, subprocess, sys, time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
VENV = os.path.join(ROOT, "target", "bench-venv")
RUNS = int(sys.argv[sys.argv.index("--runs") + 1]) if "--runs" in sys.argv else 15


def venv_python():
    py = os.path.join(VENV, "bin", "python")
    if not os.path.exists(py):
        subprocess.run([sys.executable, "-m", "venv", VENV], check=True)
    if subprocess.run([py, "-c", "import pymeshlab"], capture_output=True).returncode != 0:
        subprocess.run([py, "-m", "pip", "install", "-q", "pymeshlab"], check=True)
    return py


MESHLAB = r'''
import sys, time, statistics, pymeshlab
path, runs = sys.argv[1], int(sys.argv[2])
ms = pymeshlab.MeshSet()
ms.load_new_mesh(path)
times = []
for _ in range(runs):
    ms.set_selection_none()
    t = time.perf_counter()
    ms.compute_selection_by_self_intersections_per_face()
    times.append((time.perf_counter() - t) * 1e3)
sel = int(ms.current_mesh().selected_face_number())
print(min(times), statistics.median(times), sel)
'''


def main():
    py = venv_python()
    subprocess.run(["cargo", "build", "--release", "-q", "-p", "untangle-cli"], cwd=ROOT, check=True)
    exe = os.path.join(ROOT, "target", "release", "untangle")
    out = os.path.join(ROOT, "target", "bench-scenes")
    os.makedirs(out, exist_ok=True)
    scenes = [("folded", ["--size", "125"]), ("folded", ["--size", "224"])] + [("exploded", ["--seed", str(s)]) for s in range(3)]
    rows = []
    for name, args in scenes:
        f = os.path.join(out, f"{name}{''.join(args)}.obj")
        subprocess.run([exe, "-q", "scene", name, *args, "-o", f], check=True)
        ours = []
        for _ in range(RUNS):
            j = f + ".json"
            subprocess.run([exe, "-q", "check", f, "--json", j])
            r = json.load(open(j))
            ours.append(r["timing_ms"]["total"])
        ml = subprocess.run([py, "-c", MESHLAB, f, str(RUNS)], capture_output=True, text=True, check=True).stdout.split()
        ml_min, ml_med, ml_sel = float(ml[0]), float(ml[1]), int(ml[2])
        rows.append((f"{name} {' '.join(args)}", r["triangles"], r["intersecting_triangle_pairs"], len(r["intersecting_triangles"]),
                     ml_sel, min(ours), statistics.median(ours), ml_min, ml_med))
    print(f"{'scene':<22} {'tris':>7} {'pairs':>6} {'faces':>6} {'ML faces':>8} | {'ours min':>9} {'ours med':>9} | {'ML min':>9} {'ML med':>9} | ratio (ML/ours, min)")
    for r in rows:
        print(f"{r[0]:<22} {r[1]:>7} {r[2]:>6} {r[3]:>6} {r[4]:>8} | {r[5]:>7.2f}ms {r[6]:>7.2f}ms | {r[7]:>7.2f}ms {r[8]:>7.2f}ms | {r[7]/r[5]:.1f}x")


if __name__ == "__main__":
    main()
