#!/usr/bin/env python3
"""Render a Mitsuba 3 XML scene with Mitsuba 3 itself and compare it with photonlab.

The independent check of photonlab's XML reader and of its `path` integrator on the
scenes in experiments/scenes/mi-*.xml: Mitsuba reads the same file (its `<integrator>`
is replaced by `path` with unbounded depth, as photonlab's default), so a difference in
any convention (camera, transforms, shapes, materials, textures, emitters) shows up.

    pip install mitsuba numpy
    apt-get install -y libllvm19   # for the fast llvm_ad_rgb variant
    export DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1
    python3 tools/mitsuba_compare_xml.py SCENE.xml --spp 1024 --out /tmp/mi.exr \
        [-D res=128] [--photonlab photonlab.exr] [--block 16]

With --photonlab it prints both images' channel means, their ratio, and the 16-px block
test: the mean over each block of the per-pixel difference (mean of RGB), its standard
error from the spread of those differences inside the block (at least 1/40000 of the
block's mean, so that a noise-free background is not judged on float rounding), and how
many blocks differ by more than 4 standard errors (blocks with a mean below 0.005 are not
judged, as in `photonlab diff --block`).
"""
import argparse
import os
import sys

import numpy as np


def load_mitsuba():
    import mitsuba as mi
    for v in ("llvm_ad_rgb", "scalar_rgb"):
        try:
            mi.set_variant(v)
            return mi, v
        except Exception:  # noqa: BLE001 - try the next variant
            continue
    sys.exit("no usable Mitsuba variant (llvm_ad_rgb needs DRJIT_LIBLLVM_PATH)")


def read_exr(path):
    import mitsuba as mi
    return np.array(mi.Bitmap(path).convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float32, srgb_gamma=False), dtype=np.float64)


def block_test(test, ref, size=16, min_ref=0.005, z=4.0):
    t, r = test.mean(axis=2), ref.mean(axis=2)
    h, w = r.shape
    judged, outliers, worst = 0, 0, (0.0, None)
    for by in range(h // size):
        for bx in range(w // size):
            tb = t[by * size:(by + 1) * size, bx * size:(bx + 1) * size]
            rb = r[by * size:(by + 1) * size, bx * size:(bx + 1) * size]
            if rb.mean() <= min_ref:
                continue
            d = (tb - rb).ravel()
            # A noise-free block (a constant background) has no spread: its standard
            # error is floored at 1/40000 of its mean, so that 4 errors are 1e-4, above
            # the float rounding of the two renderers' accumulations.
            se = max(d.std(ddof=1) / np.sqrt(d.size), 2.5e-5 * rb.mean())
            judged += 1
            zz = abs(d.mean()) / se
            if zz > z:
                outliers += 1
            if zz > worst[0]:
                worst = (zz, (bx, by, tb.mean(), rb.mean()))
    return judged, outliers, worst


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("scene")
    ap.add_argument("--spp", type=int, default=256)
    ap.add_argument("--out", required=True)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--max-depth", type=int, default=-1)
    ap.add_argument("-D", action="append", default=[], help="NAME=VALUE for the scene's <default> parameters")
    ap.add_argument("--photonlab", help="photonlab EXR of the same scene and resolution to compare")
    ap.add_argument("--block", type=int, default=16)
    ap.add_argument("--reuse", action="store_true",
                    help="read --out if it exists instead of rendering it again (compare more photonlab images)")
    a = ap.parse_args()
    mi, variant = load_mitsuba()
    if a.reuse and os.path.exists(a.out):
        ref = read_exr(a.out)
        print(f"mitsuba reference reused: {a.out}, {ref.shape[1]}x{ref.shape[0]}")
    else:
        params = dict(kv.split("=", 1) for kv in a.D)
        scene = mi.load_file(a.scene, **params)
        integrator = mi.load_dict({"type": "path", "max_depth": a.max_depth})
        img = mi.render(scene, integrator=integrator, spp=a.spp, seed=a.seed)
        mi.Bitmap(img).write(a.out)
        ref = np.array(img, dtype=np.float64)
        print(f"mitsuba {mi.__version__} ({variant}): {a.out}, {ref.shape[1]}x{ref.shape[0]}, {a.spp} spp")
    if a.photonlab:
        test = read_exr(a.photonlab)
        if test.shape != ref.shape:
            sys.exit(f"size differs: photonlab {test.shape} vs mitsuba {ref.shape}")
        mt, mr = test.reshape(-1, 3).mean(0), ref.reshape(-1, 3).mean(0)
        print("mean photonlab", np.round(mt, 5), "mitsuba", np.round(mr, 5), "ratio", np.round(mt / mr, 4),
              "overall", round(mt.sum() / mr.sum(), 4))
        judged, outliers, (zw, at) = block_test(test, ref, a.block)
        print(f"{a.block}-px blocks: {judged} judged, {outliers} beyond 4 std errors; worst z {zw:.2f} at {at}")


if __name__ == "__main__":
    main()
