#!/usr/bin/env python3
"""Efficiency of photonlab `path` against Mitsuba 3's `path` on one scene TOML.

Times both whole processes (start, scene load, build, render, image write) on the same
scene file at the same resolution and sample count, runs alternating, and measures the
relative MSE of each image against one high-spp Mitsuba reference (rendered once and
kept: pass the same --ref path again to reuse it). Prints the machine first (CPU, its
widest SIMD, which sets Dr.Jit's lane count, the load, Mitsuba's version), then per
run and in total

    efficiency = (Mitsuba relMSE x seconds) / (photonlab relMSE x seconds)

so a value above 1 means photonlab reaches a given error sooner. The relMSE is the one
`photonlab diff` prints: mean over pixels and channels of (x - ref)^2 / (ref^2 + 0.01).
Each run also reports both processes' CPU time (user + system, all threads) and the
efficiency with CPU seconds in place of wall seconds, which load on a shared machine
disturbs less. Both engines use a fixed seed, so repeated runs differ in time only.

    python3 tools/mitsuba_speed.py SCENE.toml --spp 256 --ref-spp 8192 --ref /tmp/ref.exr \
        [--runs 3] [--photonlab target/release/photonlab] [--variant llvm_ad_rgb] \
        [--threads N] [--pl-arg=--sampler=halton ...]

Mitsuba runs through tools/mitsuba_compare.py (its own reader of the scene contract),
so its time includes the Python interpreter and `import mitsuba`, as a user's would.
Set DRJIT_LIBLLVM_PATH when Dr.Jit does not find libLLVM by itself.
"""
import argparse
import os
import resource
import subprocess
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))


def read_exr(path):
    import mitsuba as mi

    if not mi.variant():
        mi.set_variant("scalar_rgb")
    return np.array(mi.Bitmap(path), dtype=np.float64)[:, :, :3]


def relmse(img, ref):
    if img.shape != ref.shape:
        sys.exit(f"image {img.shape[:2]} and reference {ref.shape[:2]} differ in size")
    return float(((img - ref) ** 2 / (ref**2 + 1e-2)).mean())


def timed(cmd):
    """Wall seconds and CPU seconds (user + system of the process and its threads)."""
    ru0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    r = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    dt = time.perf_counter() - t0
    ru1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    if r.returncode != 0:
        sys.exit(f"{' '.join(cmd)} failed ({r.returncode}):\n{r.stderr}")
    return dt, (ru1.ru_utime - ru0.ru_utime) + (ru1.ru_stime - ru0.ru_stime)


def machine_line():
    """CPU model, its widest vector instructions and the load: Dr.Jit's LLVM back end
    compiles its kernels for the host's widest vectors (16 lanes with AVX-512, 8 with
    AVX2), so the same two builds compare differently on different CPUs."""
    model, fam, mod, flags = "unknown CPU", None, None, set()
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                k, _, v = line.partition(":")
                k, v = k.strip(), v.strip()
                if k == "model name":
                    model = v
                elif k == "cpu family":
                    fam = v
                elif k == "model":
                    mod = v
                elif k == "flags":
                    flags = set(v.split())
                    break
    except OSError:
        pass
    simd = "avx512" if "avx512f" in flags else "avx2" if "avx2" in flags else "sse"
    fm = f" (family {fam} model {mod})" if fam and mod else ""
    try:
        import mitsuba as mi

        mver = f", Mitsuba {mi.__version__}"
    except ImportError:
        mver = ""
    return f"machine: {model}{fm}, widest SIMD {simd}, {os.cpu_count()} logical CPUs, load average {' '.join(f'{x:.2f}' for x in os.getloadavg())}{mver}"


def mitsuba_cmd(a, spp, out):
    return [sys.executable, os.path.join(HERE, "mitsuba_compare.py"), a.scene, "--spp", str(spp), "--out", out, "--variant", a.variant]


def render_reference(a):
    """Mitsuba at --ref-spp, in passes of at most 256 spp with distinct seeds (a JIT
    variant holds a whole pass's wavefront in memory), averaged."""
    import mitsuba as mi

    sys.path.insert(0, HERE)
    import mitsuba_compare

    mi.set_variant(a.variant)
    print(f"reference: Mitsuba {a.variant}, {a.ref_spp} spp -> {a.ref}", flush=True)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        scene = mi.load_dict(mitsuba_compare.build_scene(a.scene, 256, -1, tmp))
    acc, done, seed = 0.0, 0, 0
    while done < a.ref_spp:
        n = min(256, a.ref_spp - done)
        acc = acc + np.array(mi.render(scene, spp=n, seed=1_000_003 + seed), dtype=np.float64)[:, :, :3] * n
        done, seed = done + n, seed + 1
    img = (acc / done).astype(np.float32)
    mi.Bitmap(img, mi.Bitmap.PixelFormat.RGB).write(a.ref)
    print(f"  {time.perf_counter() - t0:.1f} s", flush=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scene", help="scene TOML (photonlab scene export NAME DIR writes the built-ins)")
    ap.add_argument("--spp", type=int, default=256)
    ap.add_argument("--ref-spp", type=int, default=8192)
    ap.add_argument("--ref", required=True, help="reference EXR; rendered by Mitsuba at --ref-spp when missing")
    ap.add_argument("--runs", type=int, default=2)
    ap.add_argument("--photonlab", default=os.path.join(HERE, "..", "target", "release", "photonlab"))
    ap.add_argument("--variant", default="llvm_ad_rgb")
    ap.add_argument("--threads", type=int, help="photonlab --threads (default: its own, all cores)")
    ap.add_argument("--pl-arg", action="append", default=[], help="extra photonlab render argument (repeatable)")
    ap.add_argument("--keep", help="directory for the images (default: a temporary one)")
    a = ap.parse_args()

    if not os.path.exists(a.ref):
        render_reference(a)
    ref = read_exr(a.ref)

    tmp = a.keep or tempfile.mkdtemp(prefix="mitsuba_speed.")
    os.makedirs(tmp, exist_ok=True)
    pl_out, mi_out = os.path.join(tmp, "photonlab.exr"), os.path.join(tmp, "mitsuba.exr")
    pl = [a.photonlab, "render", "--scene", a.scene, "--spp", str(a.spp), "--quiet", "-o", pl_out] + a.pl_arg
    if a.threads:
        pl += ["--threads", str(a.threads)]
    print(machine_line(), flush=True)
    rows = []
    for run in range(a.runs):
        # Alternate which engine goes first, so a load change hits both alike.
        order = ["photonlab", "mitsuba"] if run % 2 == 0 else ["mitsuba", "photonlab"]
        t, c = {}, {}
        for who in order:
            t[who], c[who] = timed(pl if who == "photonlab" else mitsuba_cmd(a, a.spp, mi_out))
        e_pl, e_mi = relmse(read_exr(pl_out), ref), relmse(read_exr(mi_out), ref)
        eff = (e_mi * t["mitsuba"]) / (e_pl * t["photonlab"])
        eff_cpu = (e_mi * c["mitsuba"]) / (e_pl * c["photonlab"])
        rows.append((t["photonlab"], e_pl, t["mitsuba"], e_mi, eff, c["photonlab"], c["mitsuba"], eff_cpu))
        print(
            f"run {run + 1}: photonlab {t['photonlab']:.2f} s (CPU {c['photonlab']:.2f} s) relMSE {e_pl:.3e} | "
            f"mitsuba {t['mitsuba']:.2f} s (CPU {c['mitsuba']:.2f} s) relMSE {e_mi:.3e} | efficiency {eff:.2f}x (CPU {eff_cpu:.2f}x)",
            flush=True,
        )
    if not rows:
        return
    tp, ep, tm, em, _, cp, cm, _ = (sum(r[i] for r in rows) for i in range(8))
    n = len(rows)
    print(
        f"total ({n} runs): photonlab {tp / n:.2f} s (CPU {cp / n:.2f} s), relMSE {ep / n:.3e}; "
        f"mitsuba {tm / n:.2f} s (CPU {cm / n:.2f} s), relMSE {em / n:.3e}; "
        f"efficiency {(em * tm) / (ep * tp):.2f}x (per run {min(r[4] for r in rows):.2f}-{max(r[4] for r in rows):.2f}x), "
        f"by CPU time {(em * cm) / (ep * cp):.2f}x (per run {min(r[7] for r in rows):.2f}-{max(r[7] for r in rows):.2f}x)"
    )
    print(f"load average at the end: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")

if __name__ == "__main__":
    main()
