#!/usr/bin/env python3
"""Render a photonlab scene TOML (../shared/scene-format.md) with Mitsuba 3 and compare.

An independent check of the `path` integrator: this script reads the scene contract on its
own (its own OBJ/MTL reader, placement, material table, lights, camera) and hands the result
to Mitsuba 3, so a convention mismatch on either side shows up as error.

    pip install mitsuba numpy
    python3 tools/mitsuba_compare.py SCENE.toml --spp 1024 --out /tmp/mi.exr \
        [--photonlab photonlab.exr]

With --photonlab it prints per-channel means of both images, their ratio, and the relative
MSE of photonlab against Mitsuba (both images must have the same resolution).

Not supported (exits with a message): the glossy (modified Phong) material, which Mitsuba 3
has no plug-in for.
"""
import argparse
import math
import os
import sys
import tomllib

import numpy as np


def read_mtl(path):
    mats, cur = {}, None
    with open(path, encoding="utf-8", errors="replace") as f:
        for line in f:
            t = line.split("#", 1)[0].split()
            if not t:
                continue
            if t[0] == "newmtl":
                cur = {}
                mats[" ".join(t[1:])] = cur
            elif cur is not None:
                cur[t[0]] = t[1:]
    return mats


def vec(m, key, default):
    v = m.get(key)
    if not v:
        return default
    x = [float(a) for a in v[:3]]
    return x * 3 if len(x) == 1 else x


def material_from_mtl(m):
    """The contract's MTL table, checked in order."""
    if m is None:
        return {"type": "diffuse", "albedo": [0.5] * 3}
    ke = vec(m, "Ke", [0, 0, 0])
    kd = vec(m, "Kd", [0.5, 0.5, 0.5])
    illum = int(float(m["illum"][0])) if "illum" in m else -1
    d = float(m["d"][0]) if "d" in m else 1.0
    tr = float(m["Tr"][0]) if "Tr" in m else 0.0
    if max(ke) > 0:
        return {"type": "emitter", "radiance": ke, "albedo": kd}
    if illum in (4, 6, 7) or d < 1 or tr > 0:
        ni = float(m["Ni"][0]) if "Ni" in m else 1.5
        return {"type": "glass", "ior": ni if ni > 1 else 1.5, "tint": vec(m, "Tf", [1, 1, 1])}
    if illum in (3, 5):
        ks = vec(m, "Ks", [1, 1, 1])
        return {"type": "mirror", "reflectance": ks if max(ks) > 0 else [1, 1, 1]}
    ks = vec(m, "Ks", [0, 0, 0])
    ns = float(m["Ns"][0]) if "Ns" in m else 0.0
    if max(ks) > 0 and ns > 1:
        return {"type": "glossy", "kd": kd, "ks": ks, "ns": ns}
    return {"type": "diffuse", "albedo": kd}


TYPE_ALIASES = {"lambertian": "diffuse", "dielectric": "glass"}
# Per type: canonical key -> (aliases, default), as the contract's override table gives them.
OVERRIDE_KEYS = {
    "diffuse": {"albedo": (("kd",), [0.5] * 3)},
    "mirror": {"reflectance": (("ks",), [1.0] * 3)},
    "glass": {"ior": ((), 1.5), "tint": (("tf",), [1.0] * 3)},
    "glossy": {"kd": (("albedo",), [0.5] * 3), "ks": ((), [0.0] * 3), "ns": (("exponent",), 1.0)},
    "emitter": {"radiance": (("ke",), [0.0] * 3), "albedo": (("kd",), [0.5] * 3)},
}


def material_from_override(o):
    o = dict(o)
    t = o.pop("type")
    t = TYPE_ALIASES.get(t, t)
    if t not in OVERRIDE_KEYS:
        sys.exit(f"unknown material override type {t!r}")
    out = {"type": t}
    for key, (aliases, default) in OVERRIDE_KEYS[t].items():
        v = default
        for k in (key,) + aliases:
            if k in o:
                v = o.pop(k)
        if isinstance(default, list) and not isinstance(v, list):
            v = [float(v)] * 3
        out[key] = v
    if o:
        sys.exit(f"unknown key(s) {sorted(o)} in a {t} material override")
    return out


def read_obj(path):
    """Returns positions, normals, and faces grouped by material: {mtl: [(vi[3], ni[3]|None)]}."""
    vs, vns, groups, mtllib, cur = [], [], {}, None, None
    with open(path, encoding="utf-8", errors="replace") as f:
        for line in f:
            t = line.split("#", 1)[0].split()
            if not t:
                continue
            if t[0] == "v":
                vs.append([float(a) for a in t[1:4]])
            elif t[0] == "vn":
                vns.append([float(a) for a in t[1:4]])
            elif t[0] == "mtllib":
                mtllib = " ".join(t[1:])
            elif t[0] == "usemtl":
                cur = " ".join(t[1:])
            elif t[0] == "f":
                idx = []
                for c in t[1:]:
                    p = c.split("/")
                    vi = int(p[0])
                    vi = vi - 1 if vi > 0 else len(vs) + vi
                    ni = None
                    if len(p) >= 3 and p[2]:
                        ni = int(p[2])
                        ni = ni - 1 if ni > 0 else len(vns) + ni
                    idx.append((vi, ni))
                for k in range(1, len(idx) - 1):
                    tri = (idx[0], idx[k], idx[k + 1])
                    groups.setdefault(cur, []).append(tri)
    return np.array(vs, dtype=np.float64), np.array(vns, dtype=np.float64), groups, mtllib


def placement(mesh):
    s = mesh.get("scale", 1.0)
    s = np.array([s] * 3 if not isinstance(s, list) else s, dtype=np.float64)
    a = math.radians(mesh.get("rotate_y_deg", 0.0))
    c, si = math.cos(a), math.sin(a)
    r = np.array([[c, 0, si], [0, 1, 0], [-si, 0, c]])
    t = np.array(mesh.get("translate", [0, 0, 0]), dtype=np.float64)
    return s, r, t


def build_scene(toml_path, spp, max_depth, tmpdir):
    import mitsuba as mi

    with open(toml_path, "rb") as f:
        sc = tomllib.load(f)
    base = os.path.dirname(os.path.abspath(toml_path))
    cam = sc["camera"]
    w, h = cam["resolution"]
    scene = {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": max_depth, "rr_depth": 1000000 if max_depth > 0 else 5},
        "sensor": {
            "type": "perspective",
            "fov_axis": "y",
            "fov": cam["fov_y_deg"],
            "to_world": mi.ScalarTransform4f().look_at(origin=cam["eye"], target=cam["look_at"], up=cam["up"]),
            "film": {"type": "hdrfilm", "width": w, "height": h, "rfilter": {"type": "box"}, "pixel_format": "rgb"},
            "sampler": {"type": "independent", "sample_count": spp},
        },
    }
    n = 0
    for mesh in sc.get("mesh", []):
        obj = os.path.join(base, mesh["obj"])
        vs, vns, groups, mtllib = read_obj(obj)
        mtls = read_mtl(os.path.join(os.path.dirname(obj), mtllib)) if mtllib else {}
        s, r, t = placement(mesh)
        pv = (vs * s) @ r.T + t
        # Normals transform by the inverse transpose of scale∘rotate.
        pn = (vns / s) @ r.T if len(vns) else vns
        for name, tris in groups.items():
            m = material_from_override(mesh["material"]) if "material" in mesh else material_from_mtl(mtls.get(name))
            if m["type"] == "glossy":
                sys.exit(f"{obj}: material {name!r} is glossy (modified Phong); Mitsuba 3 has no equivalent")
            p = np.array([[pv[a[0]] for a in tri] for tri in tris])
            area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
            keep = area > 0
            tris = [tr for tr, k in zip(tris, keep) if k]
            p = p[keep]
            if len(tris) == 0:
                continue
            has_n = all(a[1] is not None for tri in tris for a in tri)
            nt = len(tris)
            m_mesh = mi.Mesh(f"m{n}", vertex_count=3 * nt, face_count=nt, has_vertex_normals=has_n)
            params = mi.traverse(m_mesh)
            params["vertex_positions"] = p.reshape(-1).astype(np.float32)
            params["faces"] = np.arange(3 * nt, dtype=np.uint32)
            if has_n:
                nn = np.array([[pn[a[1]] for a in tri] for tri in tris]).reshape(-1, 3)
                nn /= np.linalg.norm(nn, axis=1, keepdims=True)
                params["vertex_normals"] = nn.reshape(-1).astype(np.float32)
            params.update()
            ply = os.path.join(tmpdir, f"m{n}.ply")
            m_mesh.write_ply(ply)
            entry = {"type": "ply", "filename": ply, "face_normals": not has_n}
            if m["type"] == "diffuse":
                bsdf = {"type": "twosided", "b": {"type": "diffuse", "reflectance": {"type": "rgb", "value": m["albedo"]}}}
            elif m["type"] == "emitter":
                bsdf = {"type": "twosided", "b": {"type": "diffuse", "reflectance": {"type": "rgb", "value": m["albedo"]}}}
                entry["emitter"] = {"type": "area", "radiance": {"type": "rgb", "value": m["radiance"]}}
            elif m["type"] == "mirror":
                bsdf = {
                    "type": "twosided",
                    "b": {"type": "conductor", "material": "none", "specular_reflectance": {"type": "rgb", "value": m["reflectance"]}},
                }
            elif m["type"] == "glass":
                bsdf = {
                    "type": "dielectric",
                    "int_ior": float(m["ior"]),
                    "ext_ior": 1.0,
                    "specular_transmittance": {"type": "rgb", "value": m["tint"]},
                }
            else:
                sys.exit(f"unknown material type {m['type']}")
            entry["bsdf"] = bsdf
            scene[f"mesh{n}"] = entry
            n += 1
    for i, l in enumerate(sc.get("light", [])):
        if l["type"] == "point":
            scene[f"light{i}"] = {"type": "point", "position": l["position"], "intensity": {"type": "rgb", "value": l["intensity"]}}
        elif l["type"] == "spot":
            pos, d = np.array(l["position"]), np.array(l["direction"])
            scene[f"light{i}"] = {
                "type": "spot",
                "to_world": mi.ScalarTransform4f().look_at(origin=pos.tolist(), target=(pos + d).tolist(), up=[0.3, 1.0, 0.1]),
                "intensity": {"type": "rgb", "value": l["intensity"]},
                "cutoff_angle": l["falloff_deg"],
                "beam_width": l["cone_deg"],
            }
        elif l["type"] == "directional":
            scene[f"light{i}"] = {"type": "directional", "direction": l["direction"], "irradiance": {"type": "rgb", "value": l["irradiance"]}}
    return scene


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scene")
    ap.add_argument("--spp", type=int, default=1024)
    ap.add_argument("--max-depth", type=int, default=-1, help="Mitsuba max_depth (-1: unbounded, RR from depth 5)")
    ap.add_argument("--out", required=True)
    ap.add_argument("--variant", default="scalar_rgb", help="Mitsuba variant (llvm_ad_rgb is faster where its LLVM works)")
    ap.add_argument("--photonlab", help="photonlab EXR of the same scene to compare against")
    a = ap.parse_args()
    import mitsuba as mi

    mi.set_variant(a.variant)
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        scene = mi.load_dict(build_scene(a.scene, a.spp, a.max_depth, tmp))
    img = np.array(mi.render(scene))[:, :, :3]
    mi.Bitmap(img.astype(np.float32), mi.Bitmap.PixelFormat.RGB).write(a.out)
    print(f"mitsuba: {a.out}  mean {img.reshape(-1, 3).mean(0)}")
    if a.photonlab:
        b = np.array(mi.Bitmap(a.photonlab))[:, :, :3]
        if b.shape != img.shape:
            sys.exit(f"{a.photonlab}: resolution {b.shape[:2]} differs from {img.shape[:2]}")
        mb, mm = b.reshape(-1, 3).mean(0), img.reshape(-1, 3).mean(0)
        rel = ((b - img) ** 2 / (img**2 + 1e-2)).mean()
        print(f"photonlab mean {mb}\nratio photonlab/mitsuba {mb / mm}\nrelMSE(photonlab vs mitsuba) {rel:.5f}")


if __name__ == "__main__":
    main()
