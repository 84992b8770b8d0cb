#!/usr/bin/env python3
"""Instructions, loads, L1 misses and branch mispredictions per ray, photonlab against
Embree, counted by valgrind's cachegrind (a simulated cache and branch predictor: the
counts are exact and repeatable where timings on a shared VM vary by 20 %).

Each engine runs once per ray set with only that set traced and once with none
(build and ray generation alone); the difference divided by the ray count is the
cost of one query. photonlab traces one set with `bench accel --sets`; the Embree
harness has no such option, so a copy of its source is patched (one `RUN_ONLY`
test before each timed set) and compiled in a scratch folder (needs
libembree-dev, as the harness's own build.sh).

    python3 tools/ray_instructions.py --harness-dir ../shared/bench/embree \
        --obj ../shared/scenes/sponza-dabrovic/sponza.obj --inside --rays 200000
"""

import argparse
import collections
import os
import pathlib
import subprocess
import sys
import tempfile

EVENTS = ["Ir", "Dr", "D1mr", "Bc", "Bcm"]
SETS = {"camera": "camera/intersect1", "diffuse": "diffuse/intersect1", "shadow": "shadow/occluded1"}
PATCH_AT = "        if (runs[r].n == 0) continue;\n"
PATCH = (
    '        { const char *only = getenv("RUN_ONLY"); char tag[64];\n'
    '          snprintf(tag, sizeof tag, "%s/%s", runs[r].rays, runs[r].api);\n'
    "          if (only && strcmp(only, tag)) continue; }\n"
)


def totals(path):
    """Sums every event of a cachegrind output file over all functions."""
    events, tot = None, collections.Counter()
    with open(path) as f:
        for line in f:
            if line.startswith("events:"):
                events = line.split()[1:]
            elif line[:1].isdigit():
                for name, v in zip(events, map(int, line.split()[1:])):
                    tot[name] += v
    return tot


def cachegrind(cmd, out, env=None):
    full = ["valgrind", "--tool=cachegrind", "--cache-sim=yes", "--branch-sim=yes", f"--cachegrind-out-file={out}"] + cmd
    try:
        r = subprocess.run(full, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    except FileNotFoundError:
        sys.exit("ray_instructions: valgrind is not installed (apt-get install valgrind)")
    if r.returncode != 0:
        sys.exit(f"ray_instructions: {' '.join(cmd)} failed:\n{r.stderr[-2000:]}")
    return totals(out)


def build_harness(harness_dir, work):
    src = pathlib.Path(harness_dir) / "embree_bench.c"
    try:
        text = src.read_text()
    except OSError as e:
        sys.exit(f"ray_instructions: cannot read {src}: {e}")
    if PATCH_AT not in text:
        sys.exit(f"ray_instructions: {src}: the line to patch (`{PATCH_AT.strip()}`) is not there")
    patched = pathlib.Path(work) / "embree_bench_one_set.c"
    patched.write_text(text.replace(PATCH_AT, PATCH_AT + PATCH, 1))
    exe = pathlib.Path(work) / "embree_bench_one_set"
    cc = ["gcc", "-O3", "-march=native", "-std=c11", "-o", str(exe), str(patched), "-lembree3", "-lpthread", "-lm"]
    r = subprocess.run(cc, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"ray_instructions: compiling the patched harness failed (libembree-dev installed?):\n{r.stderr}")
    return exe


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--obj", required=True, help="mesh (OBJ) both engines load")
    ap.add_argument("--inside", action="store_true", help="camera at the bounding-box centre")
    ap.add_argument("--rays", type=int, default=200_000, help="rays per set (valgrind runs ~50x slower)")
    ap.add_argument("--harness-dir", help="Embree harness sources (embree_bench.c); without it photonlab only")
    ap.add_argument("--photonlab", default="target/release/photonlab", help="photonlab binary")
    ap.add_argument("--accel", default="bvh8")
    ap.add_argument("--sets", default="camera,diffuse,shadow")
    a = ap.parse_args()
    sets = a.sets.split(",")
    for s in sets:
        if s not in SETS:
            sys.exit(f"ray_instructions: unknown set `{s}` (known: {', '.join(SETS)})")
    inside = ["--inside"] if a.inside else []
    rows = []
    with tempfile.TemporaryDirectory() as work:
        pl = [a.photonlab, "bench", "accel", "--obj", a.obj, "--rays", str(a.rays), "--accel", a.accel, "--no-counts"] + inside
        base = cachegrind(pl + ["--sets", ""], os.path.join(work, "pl_none.out"))
        for s in sets:
            t = cachegrind(pl + ["--sets", s], os.path.join(work, f"pl_{s}.out"))
            rows.append((f"photonlab {a.accel}", s, {e: (t[e] - base[e]) / a.rays for e in EVENTS}))
        if a.harness_dir:
            exe = build_harness(a.harness_dir, work)
            em = [str(exe), a.obj, "--rays", str(a.rays), "--builds", "1"] + inside
            env = dict(os.environ, RUN_ONLY="none")
            base = cachegrind(em, os.path.join(work, "em_none.out"), env)
            for s in sets:
                env = dict(os.environ, RUN_ONLY=SETS[s])
                t = cachegrind(em, os.path.join(work, f"em_{s}.out"), env)
                rows.append(("embree", s, {e: (t[e] - base[e]) / a.rays for e in EVENTS}))
    print("| engine | rays | instructions | loads | L1 load misses | cond. branches | mispredicted |")
    print("|---|---|---:|---:|---:|---:|---:|")
    for eng, s, d in sorted(rows, key=lambda r: (list(SETS).index(r[1]), r[0])):
        print(f"| {eng} | {s} | " + " | ".join(f"{d[e]:.1f}" for e in EVENTS) + " |")


if __name__ == "__main__":
    main()
