#!/usr/bin/env python3
"""Checks that two `untangle` binaries give the same analysis: runs `untangle check --json` with
each on the same inputs and compares the reports with `timing_ms` removed.

Usage (from the repository root):
    python3 bench/compare_reports.py OLD_BINARY NEW_BINARY [SHARED_DIR]

Inputs: scenes written by the new binary (exploded seeds 0-7 and sizes 20/28/40, folded sizes
22/30/40/60/125, the seven rudimentary cases), and, when SHARED_DIR (default ../shared) has them,
the untangling26 units and the ARCSim garments (alone and all together). Prints one line per
input and exits with 1 when any report differs. Used to show that a speed change left the analysis output unchanged."""
import json, os, subprocess, sys, tempfile

old, new = sys.argv[1], sys.argv[2]
shared = sys.argv[3] if len(sys.argv) > 3 else os.path.join(os.path.dirname(__file__), "..", "..", "shared")


def report(binary, files, out):
    subprocess.run([binary, "check", *files, "--json", out, "-q"], check=False)
    with open(out) as f:
        r = json.load(f)
    r.pop("timing_ms", None)
    return r


with tempfile.TemporaryDirectory() as d:
    cases = []
    scenes = [("exploded", ["--seed", str(s)]) for s in range(8)]
    scenes += [("exploded", ["--size", str(n), "--seed", "0"]) for n in (20, 28, 40)]
    scenes += [("folded", ["--size", str(n)]) for n in (22, 30, 40, 60, 125)]
    scenes += [(k, []) for k in ("closed", "ll", "eight", "cross", "bbii", "bibi", "bli")]
    for name, extra in scenes:
        path = os.path.join(d, f"{name}{'_'.join([''] + extra)}.obj")
        subprocess.run([new, "scene", name, *extra, "-o", path, "-q"], check=True)
        cases.append([path])
    units = os.path.join(shared, "data", "untangling26-units")
    if os.path.isdir(units):
        cases += [[os.path.join(units, f)] for f in sorted(os.listdir(units)) if f.endswith(".obj")]
    meshes = os.path.join(shared, "data", "arcsim", "meshes")
    garments = [os.path.join(meshes, f"{g}.obj") for g in ("tshirt", "dress3", "pants3", "jacket")]
    if all(os.path.exists(g) for g in garments):
        cases += [[g] for g in garments] + [garments]
    else:
        print(f"note: {meshes} not found; ARCSim garments skipped")
    differ = 0
    for files in cases:
        a = report(old, files, os.path.join(d, "a.json"))
        b = report(new, files, os.path.join(d, "b.json"))
        same = a == b
        differ += not same
        print(f"{'same' if same else 'DIFFERENT'}  {' + '.join(os.path.basename(f) for f in files)}")
    print(f"{len(cases) - differ} of {len(cases)} reports identical (timing removed)")
    sys.exit(1 if differ else 0)
