#!/usr/bin/env python3
"""Decision hashes: a short fingerprint of everything the simulator and the Cha & Ko loop decide,
without the timings, for 1 and 2 threads. Two builds with the same hashes made the same
decisions (bit-identical step reports); a speed change should leave them unchanged.

Usage (from the repository root, after `cargo build --release -p untangle --examples`):
    python3 bench/decisions.py [EXAMPLES_DIR] [--shared PATH]

EXAMPLES_DIR defaults to target/release/examples. Needs ../shared (or --shared / UNTANGLE_SHARED)
for the ARCSim t-shirt. Runs, with RAYON_NUM_THREADS = 1 and 2:
  bw      sim_bench 2 (Baraff & Witkin, 6 steps): every step report (JSON)
  pd      the same with UNTANGLE_INTEGRATOR=pd
  tangled sim_bench tangled 1 2 4 (m-CCH steps of a tangled shirt): the step table
  chako   cha_ko_bench 2 1 10 (the Cha & Ko loop, BW): every simulator step report
  pdloop  the same with UNTANGLE_INTEGRATOR=pd
and prints one line per thread count: `name hash ...` (first 8 hex digits of a SHA-256 over the
reports with every timing field removed). Exits 1 when 1 and 2 threads differ.

These hashes are not those of the /tmp scripts of sessions 17-25 (their stripping was not kept);
compare only hashes printed by this script."""
import argparse, hashlib, json, os, re, subprocess, sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
cli = argparse.ArgumentParser(description="decision hashes for 1 and 2 threads")
cli.add_argument("examples", nargs="?", default=os.path.join(ROOT, "target", "release", "examples"))
cli.add_argument("--shared", default=os.environ.get("UNTANGLE_SHARED", os.path.join(ROOT, "..", "shared")))
opts = cli.parse_args()
EX, SHARED = opts.examples, opts.shared
TIMING = re.compile(r"(_ms$|^timing$|^ms$|^wall|^cpu)")


def strip(x):
    """The value without timing fields (keys ending in _ms, `timing`, wall/cpu times)."""
    if isinstance(x, dict):
        return {k: strip(v) for k, v in x.items() if not TIMING.search(k)}
    if isinstance(x, list):
        return [strip(v) for v in x]
    return x


def json_lines(text):
    out = []
    for line in text.splitlines():
        line = line.strip()
        if line.startswith("{"):
            out.append(json.dumps(strip(json.loads(line)), sort_keys=True))
    return out


def table_without_times(text, time_columns):
    """Rows of a whitespace table whose first cell is an integer, time columns dropped."""
    rows = []
    for line in text.splitlines():
        cells = line.split()
        if cells and cells[0].isdigit():
            rows.append(" ".join(c for i, c in enumerate(cells) if i not in time_columns))
    return rows


def run(example, example_args, threads, env_extra, stream):
    env = {k: v for k, v in os.environ.items() if not k.startswith(("UNTANGLE_", "CHAKO_", "SIM_BENCH_"))}
    env.update(RAYON_NUM_THREADS=str(threads), UNTANGLE_SHARED=SHARED, **env_extra)
    r = subprocess.run([os.path.join(EX, example), *example_args], env=env,
                       capture_output=True, text=True, check=True)
    return r.stdout if stream == "stdout" else r.stderr


def digest(lines):
    if not lines:
        sys.exit("no deterministic output captured: is the shared data there?")
    return hashlib.sha256("\n".join(lines).encode()).hexdigest()[:8]


CASES = [
    ("bw", lambda t: json_lines(run("sim_bench", ["2"], t,
                                    {"SIM_BENCH_VERBOSE": "1", "SIM_BENCH_STEPS": "6"}, "stderr"))),
    ("pd", lambda t: json_lines(run("sim_bench", ["2"], t,
                                    {"SIM_BENCH_VERBOSE": "1", "SIM_BENCH_STEPS": "6",
                                     "UNTANGLE_INTEGRATOR": "pd"}, "stderr"))),
    # step pairs red-v [step-ms cg broad prox ccd zones] cg-it ccd-i zone-v quit
    ("tangled", lambda t: table_without_times(
        run("sim_bench", ["tangled", "1", "2", "4"], t, {}, "stdout"), {3, 4, 5, 6, 7, 8})),
    ("chako", lambda t: json_lines(run("cha_ko_bench", ["2", "1", "10"], t,
                                       {"CHA_KO_BENCH_VERBOSE": "1"}, "stderr"))),
    ("pdloop", lambda t: json_lines(run("cha_ko_bench", ["2", "1", "10"], t,
                                        {"CHA_KO_BENCH_VERBOSE": "1",
                                         "UNTANGLE_INTEGRATOR": "pd"}, "stderr"))),
]

results = {}
for threads in (1, 2):
    hashes = [(name, digest(case(threads))) for name, case in CASES]
    results[threads] = hashes
    print(f"threads {threads}: " + " ".join(f"{n} {h}" for n, h in hashes), flush=True)
if results[1] != results[2]:
    print("1 and 2 threads differ")
    sys.exit(1)
