#!/usr/bin/env python3
"""Side-by-side benchmark: untangle's full intersection analysis vs MeshLab's per-face
self-intersection selection (pymeshlab), on the same scenes, in the same run.

Usage (from the repository root):
    python3 bench/analysis_vs_meshlab.py [--runs N] [--rounds R] [--instructions]

Installs pymeshlab into target/bench-venv (benchmark only; never a test dependency), builds the
release binary, writes the scenes with `untangle scene`, then times:
  - untangle, warm (like MeshLab's repeated calls in one process): the `analysis_bench` example
    on the same generators, N analyses in one process, minimum and median, with 2 worker threads
    and with 1 (MeshLab's filter is single-threaded);
  - untangle, cold: `untangle check --json` as a fresh process per run, the report's
    timing_ms.total (broad phase + crossings + paths + kinds + regions + colouring);
  - MeshLab: compute_selection_by_self_intersections_per_face (detection only), min and median.
MeshLab's and our warm timings are taken in R rounds (default 3), interleaved per scene, and the
best round of each is reported: a slow spell of the shared host then hits both tools alike.
It also cross-checks the number of intersecting faces: MeshLab's selection must equal our
`intersecting_triangles` on generic scenes (where no triangle merely touches another).

With --instructions it also counts instructions per call with valgrind's callgrind (total with 3
calls minus total with 1 call, halved), single-threaded: a measure independent of machine load.
Ours comes from the analysis_bench example on the same scenes (same generators and parameters)."""
import json, os, statistics, subprocess, sys, time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
VENV = os.path.join(ROOT, "target", "bench-venv")
RUNS = int(sys.argv[sys.argv.index("--runs") + 1]) if "--runs" in sys.argv else 15
ROUNDS = int(sys.argv[sys.argv.index("--rounds") + 1]) if "--rounds" in sys.argv else 3
INSTRUCTIONS = "--instructions" in sys.argv


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


ML_CG = r'''
import sys, pymeshlab
ms = pymeshlab.MeshSet()
ms.load_new_mesh(sys.argv[1])
for _ in range(int(sys.argv[2])):
    ms.set_selection_none()
    ms.compute_selection_by_self_intersections_per_face()
'''


def callgrind_total(cmd, env=None):
    out = os.path.join(ROOT, "target", "cg.tmp")
    subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={out}", *cmd],
                   capture_output=True, env=env, check=True)
    ann = subprocess.run(["callgrind_annotate", out], capture_output=True, text=True).stdout
    for line in ann.splitlines():
        if "PROGRAM TOTALS" in line:
            return int(line.split()[0].replace(",", ""))
    raise RuntimeError("no callgrind total")


def per_call(cmd_for_runs, env=None):
    return (callgrind_total(cmd_for_runs(3), env) - callgrind_total(cmd_for_runs(1), env)) / 2


def main():
    py = venv_python()
    subprocess.run(["cargo", "build", "--release", "-q", "-p", "untangle-cli"], cwd=ROOT, check=True)
    exe = os.path.join(ROOT, "target", "release", "untangle")
    out = os.path.join(ROOT, "target", "bench-scenes")
    os.makedirs(out, exist_ok=True)
    big = [20, 28, 40]  # larger exploded balls (seed 0): crossing pairs grow with the square of the triangles
    scenes = [("folded", ["--size", "125"]), ("folded", ["--size", "224"])] + [("exploded", ["--seed", str(s)]) for s in range(3)] \
        + [("exploded", ["--size", str(n), "--seed", "0"]) for n in big]
    subprocess.run(["cargo", "build", "--release", "-q", "-p", "untangle", "--example", "analysis_bench"], cwd=ROOT, check=True)
    bench = os.path.join(ROOT, "target", "release", "examples", "analysis_bench")
    only_of = {"folded --size 125": "folded n=125 dents=4", "folded --size 224": "folded n=224 dents=4",
               **{f"exploded --seed {s}": f"exploded seed={s}" for s in range(3)},
               **{f"exploded --size {n} --seed 0": f"exploded n={n} seed=0" for n in big}}

    def warm(only, threads):
        env = dict(os.environ, RAYON_NUM_THREADS=str(threads))
        text = subprocess.run([bench, "--runs", str(RUNS), "--only", only], capture_output=True,
                              text=True, env=env, check=True).stdout
        line = next(l for l in text.splitlines() if l.startswith(only))
        return float(line.split("median")[1].split()[0]), float(line.split("min")[1].split()[0])

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
        key = f"{name} {' '.join(args)}"
        # ROUNDS rounds, MeshLab and ours interleaved, each the min (and the median of the round
        # with the min): a slow spell of the host hits both tools alike rather than one.
        mls, w2s, w1s = [], [], []
        for _ in range(ROUNDS):
            ml = subprocess.run([py, "-c", MESHLAB, f, str(RUNS)], capture_output=True, text=True, check=True).stdout.split()
            mls.append((float(ml[0]), float(ml[1]), int(ml[2])))
            w2s.append(warm(only_of[key], 2)[::-1])
            w1s.append(warm(only_of[key], 1)[::-1])
        ml_min, ml_med, ml_sel = min(mls)
        (w2_min, w2_med), (w1_min, w1_med) = min(w2s), min(w1s)
        rows.append((key, r["triangles"], r["intersecting_triangle_pairs"], len(r["intersecting_triangles"]),
                     ml_sel, min(ours), w2_min, w2_med, w1_min, ml_min, ml_med))
    print("wall clock in ms (min over runs unless 'med'); ratios = MeshLab min / ours min")
    print(f"{'scene':<20} {'tris':>7} {'pairs':>6} {'faces':>6} {'ML faces':>8} | {'cold':>6} {'warm2':>6} {'med':>6} {'warm1':>6} | {'ML':>6} {'ML med':>6} | warm2  warm1  cold")
    for r in rows:
        print(f"{r[0]:<20} {r[1]:>7} {r[2]:>6} {r[3]:>6} {r[4]:>8} | {r[5]:>6.2f} {r[6]:>6.2f} {r[7]:>6.2f} {r[8]:>6.2f} | {r[9]:>6.2f} {r[10]:>6.2f} | "
              f"{r[9]/r[6]:4.1f}x {r[9]/r[8]:4.1f}x {r[9]/r[5]:4.1f}x")
    if INSTRUCTIONS:
        env = dict(os.environ, RAYON_NUM_THREADS="1")
        print("\ninstructions per call (callgrind, single thread):")
        for name, only, f in [("folded --size 125", "folded n=125 dents=4", "folded--size125.obj")] + [
                (f"exploded --seed {s}", f"exploded seed={s}", f"exploded--seed{s}.obj") for s in range(3)] + [
                (f"exploded --size {n}", f"exploded n={n} seed=0", f"exploded--size{n}--seed0.obj") for n in big]:
            ours = per_call(lambda n: [bench, "--runs", str(n), "--only", only], env)
            ml = per_call(lambda n: [py, "-c", ML_CG, os.path.join(out, f), str(n)])
            print(f"{name:<22} ours {ours/1e6:8.1f} M   MeshLab {ml/1e6:8.1f} M   ratio {ml/ours:.2f}x")


if __name__ == "__main__":
    main()
