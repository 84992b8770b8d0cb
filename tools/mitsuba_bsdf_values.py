#!/usr/bin/env python3
"""Print Mitsuba 3's BSDF values (f·cos and pdf) for a few direction pairs: the
reference numbers that src/material/*'s `matches_mitsuba_values` tests check.

    pip install mitsuba numpy && python3 tools/mitsuba_bsdf_values.py

Mitsuba's convention: si.wi is the direction towards the viewer (photonlab's `wo`),
the evaluated direction is towards the light (photonlab's `wi`); normal +z.
"""
import mitsuba as mi
import numpy as np

mi.set_variant("scalar_rgb")


def unit(v):
    v = np.array(v, float)
    return v / np.linalg.norm(v)


PAIRS = [(unit([0.3, 0.1, 0.9]), unit([-0.5, 0.2, 0.7])), (unit([0.8, 0.0, 0.2]), unit([-0.1, 0.6, 0.3]))]
# Three more (normal viewer, the coating's mirror peak, a grazing viewer), used with the
# smooth GGX plastic only.
MORE_PAIRS = [(unit([0.0, 0.0, 1.0]), unit([0.2, 0.1, 0.9])), (unit([0.5, 0.0, 0.5]), unit([-0.5, 0.02, 0.5])),
              (unit([0.9, 0.0, 0.1]), unit([0.0, 0.3, 0.95]))]
BSDFS = {
    "roughplastic beckmann 0.3": {"type": "roughplastic", "distribution": "beckmann", "alpha": 0.3,
                                  "diffuse_reflectance": {"type": "rgb", "value": [0.6, 0.6, 0.55]}},
    "roughplastic ggx 0.15": {"type": "roughplastic", "distribution": "ggx", "alpha": 0.15,
                              "diffuse_reflectance": {"type": "rgb", "value": [0.5, 0.5, 0.5]}},
    "roughplastic ggx 0.05": {"type": "roughplastic", "distribution": "ggx", "alpha": 0.05,
                              "diffuse_reflectance": {"type": "rgb", "value": [0.5, 0.5, 0.5]}},
    "plastic": {"type": "plastic", "diffuse_reflectance": {"type": "rgb", "value": [0.7, 0.1, 0.1]}},
    "roughconductor Au beckmann 0.2": {"type": "roughconductor", "material": "Au", "distribution": "beckmann",
                                       "alpha": 0.2},
}

for name, d in BSDFS.items():
    b = mi.load_dict(d)
    for viewer, light in PAIRS + (MORE_PAIRS if name == "roughplastic ggx 0.05" else []):
        si = mi.SurfaceInteraction3f()
        si.wi = mi.Vector3f(viewer)
        si.n = mi.Normal3f(0, 0, 1)
        si.sh_frame = mi.Frame3f(si.n)
        ctx = mi.BSDFContext()
        f = b.eval(ctx, si, mi.Vector3f(light))
        p = b.pdf(ctx, si, mi.Vector3f(light))
        print(f"{name}: viewer {np.round(viewer, 4)} light {np.round(light, 4)} f*cos {f} pdf {p}")
