#!/usr/bin/env python3
"""Validate scenes/cornell-box/scene.gltf (written by make_cornell_box.py).

Always (numpy only; pygltflib is used too when installed):
  * structure: asset 2.0, buffer byteLength == scene.bin size, bufferViews inside the buffer,
    accessors inside their views, POSITION accessors with correct min/max, indices in range,
    extensionsUsed lists KHR_materials_emissive_strength, the camera node exists;
  * geometry: in world space every triangle's winding normal (counter-clockwise = front, glTF's
    rule) agrees with its stored NORMAL, and the emissive triangles face down (-y).
With --mitsuba (needs `pip install mitsuba`):
  * camera/geometry against Mitsuba itself: a numpy ray caster that follows only the glTF spec
    (camera looks down -Z, +X right, +Y up, yfov vertical) computes the albedo seen through each
    pixel centre; it must match Mitsuba's albedo AOV of mitsuba.cornell_box() (same resolution,
    box filter) on >= 99.9% of the pixels not next to an edge, the red wall must be on the left, and the light must be
    seen from its emitting (front) side;
  * round trip: the glTF's triangles (no vertex normals, so Mitsuba uses the winding normal),
    materials and emitter loaded into Mitsuba and rendered must give the same mean radiance as
    mitsuba.cornell_box() within 2%.

    python3 assets-scripts/check_cornell_gltf.py [--mitsuba] [--variant scalar_rgb] [--resolution 128]
"""

import argparse
import json
import math
import os
import sys

import numpy as np

COMP = {5120: ("i1", 1), 5121: ("u1", 1), 5122: ("<i2", 2), 5123: ("<u2", 2), 5125: ("<u4", 4),
        5126: ("<f4", 4)}
NCOMP = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}


class Fail(Exception):
    pass


def check(cond, msg):
    if not cond:
        raise Fail(msg)


def load(path):
    with open(path) as f:
        g = json.load(f)
    check(g["asset"]["version"] == "2.0", "asset.version != 2.0")
    check(len(g["buffers"]) == 1, "expected one buffer")
    b = g["buffers"][0]
    bin_path = os.path.join(os.path.dirname(path), b["uri"])
    data = open(bin_path, "rb").read()
    check(len(data) == b["byteLength"], f"buffer byteLength {b['byteLength']} != file size {len(data)}")
    return g, data


def accessor(g, data, i):
    a = g["accessors"][i]
    v = g["bufferViews"][a["bufferView"]]
    dt, size = COMP[a["componentType"]]
    n = NCOMP[a["type"]]
    start = v.get("byteOffset", 0) + a.get("byteOffset", 0)
    check(v.get("byteOffset", 0) + v["byteLength"] <= len(data), f"bufferView {a['bufferView']} outside buffer")
    check(v.get("byteOffset", 0) % size == 0 and start % size == 0, f"accessor {i} misaligned")
    check(a.get("byteOffset", 0) + a["count"] * n * size <= v["byteLength"], f"accessor {i} outside its view")
    arr = np.frombuffer(data, dtype=dt, count=a["count"] * n, offset=start)
    return a, (arr.reshape(a["count"], n) if n > 1 else arr)


def node_matrix(n):
    check("matrix" in n, f"node {n.get('name')} has no matrix")
    return np.array(n["matrix"], dtype=np.float64).reshape(4, 4).T  # column-major -> row-major


def world_triangles(g, data):
    """[(node name, material index, tris (T,3,3) world, stored normals (T,3) world)]."""
    out = []
    for n in g["nodes"]:
        if "mesh" not in n:
            continue
        m = node_matrix(n)
        nm = np.linalg.inv(m[:3, :3]).T
        for p in g["meshes"][n["mesh"]]["primitives"]:
            check(p.get("mode", 4) == 4, "non-triangle primitive")
            pa, pos = accessor(g, data, p["attributes"]["POSITION"])
            check("min" in pa and "max" in pa, "POSITION accessor without min/max")
            check(np.allclose(pa["min"], pos.min(0)) and np.allclose(pa["max"], pos.max(0)),
                  "POSITION min/max wrong")
            _, nor = accessor(g, data, p["attributes"]["NORMAL"])
            ia, idx = accessor(g, data, p["indices"])
            check(ia["type"] == "SCALAR" and idx.max() < len(pos), "index out of range")
            idx = idx.reshape(-1, 3)
            wp = pos.astype(np.float64) @ m[:3, :3].T + m[:3, 3]
            wn = nor.astype(np.float64) @ nm.T
            wn /= np.linalg.norm(wn, axis=1, keepdims=True)
            out.append((n["name"], p["material"], wp[idx], wn[idx[:, 0]]))
            # stored normals must be flat per triangle
            check(np.allclose(nor[idx[:, 0]], nor[idx[:, 1]]) and np.allclose(nor[idx[:, 0]], nor[idx[:, 2]]),
                  f"{n['name']}: normals not flat")
    return out


def camera(g):
    cams = [n for n in g["nodes"] if "camera" in n]
    check(len(cams) == 1 and cams[0]["name"] == "camera", "expected one camera node named 'camera'")
    c = g["cameras"][cams[0]["camera"]]
    check(c["type"] == "perspective", "camera not perspective")
    return node_matrix(cams[0]), c["perspective"]


def structural(path):
    g, data = load(path)
    check("KHR_materials_emissive_strength" in g.get("extensionsUsed", []), "extension not in extensionsUsed")
    tris = world_triangles(g, data)
    emissive = 0
    for name, mat, t, sn in tris:
        wn = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
        wn /= np.linalg.norm(wn, axis=1, keepdims=True)
        check(np.all(np.einsum("ij,ij->i", wn, sn) > 0.999), f"{name}: winding disagrees with NORMAL")
        mt = g["materials"][mat]
        check(mt["pbrMetallicRoughness"]["metallicFactor"] == 0 and mt["extras"]["bsdf"] == "diffuse",
              f"material {mt['name']} not diffuse")
        if any(mt.get("emissiveFactor", [0, 0, 0])):
            emissive += len(t)
            check(np.allclose(wn, [0, -1, 0], atol=1e-6), f"{name}: emitter not facing down")
    check(emissive == 2, f"expected 2 emissive triangles, got {emissive}")
    camera(g)
    summary = f"{len(g['nodes'])} nodes, {sum(len(t[2]) for t in tris)} triangles, {len(data)}-byte buffer"
    try:
        import pygltflib
        pg = pygltflib.GLTF2().load(path)
        check(len(pg.nodes) == len(g["nodes"]) and len(pg.accessors) == len(g["accessors"]), "pygltflib disagrees")
        summary += ", pygltflib loads it"
    except ImportError:
        summary += ", pygltflib not installed (skipped)"
    return g, data, tris, summary


# ------------------------------------------------------------------------ Mitsuba comparisons


def raycast_albedo(g, tris, w, h):
    """Albedo (and front/back of the light) seen through each pixel centre, glTF camera rules only."""
    cm, persp = camera(g)
    aspect = w / h
    th = math.tan(persp["yfov"] / 2)
    xs = ((np.arange(w) + 0.5) / w * 2 - 1) * th * aspect
    ys = (1 - (np.arange(h) + 0.5) / h * 2) * th
    X, Y = np.meshgrid(xs, ys)
    d_cam = np.stack([X, Y, -np.ones_like(X)], -1).reshape(-1, 3)
    d = d_cam @ cm[:3, :3].T
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = cm[:3, 3]
    best = np.full(len(d), np.inf)
    albedo = np.zeros((len(d), 3))
    light_front = np.zeros(len(d), bool)
    light_hit = np.zeros(len(d), bool)
    for name, mat, t, _ in tris:
        mt = g["materials"][mat]
        col = np.array(mt["pbrMetallicRoughness"]["baseColorFactor"][:3])
        is_light = any(mt.get("emissiveFactor", [0, 0, 0]))
        for tri in t:  # Moller-Trumbore, vectorised over rays
            e1, e2 = tri[1] - tri[0], tri[2] - tri[0]
            pv = np.cross(d, e2)
            det = pv @ e1
            ok = np.abs(det) > 1e-12
            inv = np.where(ok, 1 / np.where(ok, det, 1), 0)
            tv = o - tri[0]
            u = (pv @ tv) * inv
            qv = np.cross(tv, e1)
            v = (d @ qv) * inv
            tt = (qv @ e2) * inv
            hit = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (tt > 1e-6) & (tt < best)
            best[hit] = tt[hit]
            albedo[hit] = col
            light_hit[hit] = is_light
            # front side seen iff the ray travels against the winding normal
            light_front[hit] = is_light & ((d[hit] @ np.cross(e1, e2)) < 0)
    return albedo.reshape(h, w, 3), light_hit.reshape(h, w), light_front.reshape(h, w)


def import_mitsuba(variant):
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    from make_cornell_box import import_mitsuba as imp
    return imp(variant)


def mitsuba_checks(g, tris, variant, res, spp):
    mi = import_mitsuba(variant)
    ref = mi.cornell_box()
    ref["sensor"]["film"]["width"] = ref["sensor"]["film"]["height"] = res

    # 1. albedo AOV vs the glTF ray caster
    aov = dict(ref)
    aov["integrator"] = {"type": "aov", "aovs": "a:albedo"}
    aov["sensor"] = dict(ref["sensor"])
    aov["sensor"]["film"] = dict(ref["sensor"]["film"], rfilter={"type": "box"})
    img = np.array(mi.render(mi.load_dict(aov), spp=64))[..., :3]
    ours, light_hit, light_front = raycast_albedo(g, tris, res, res)
    agree = np.all(np.abs(img - ours) < 0.02, axis=-1)
    edge = np.zeros_like(agree)  # pixels next to an albedo edge of the ray-cast image: mixed in Mitsuba's
    for ax in (0, 1):
        dif = np.any(np.abs(np.diff(ours, axis=ax)) > 1e-6, axis=-1)
        lo = [slice(None)] * 2
        hi = [slice(None)] * 2
        lo[ax], hi[ax] = slice(None, -1), slice(1, None)
        edge[tuple(lo)] |= dif
        edge[tuple(hi)] |= dif
    inner = agree[~edge].mean()
    print(f"albedo: glTF ray caster vs Mitsuba albedo AOV ({res}x{res}): agree on {agree.mean() * 100:.2f}% of "
          f"all pixels, {inner * 100:.3f}% of the {(~edge).sum()} pixels off albedo edges")
    check(inner >= 0.999, "camera/geometry mismatch with Mitsuba")
    red = np.array(g["materials"][[m["name"] for m in g["materials"]].index("red")]
                   ["pbrMetallicRoughness"]["baseColorFactor"][:3])
    is_red = np.all(np.abs(ours - red) < 1e-6, axis=-1)
    cols = np.nonzero(is_red.any(0))[0]
    print(f"red wall covers image columns {cols.min()}..{cols.max()} of {res} (left side)")
    check(cols.max() < res // 2, "red wall not on the left")
    check(light_hit.sum() > 0 and (light_front == light_hit).all(), "light not seen from its front side")
    print(f"light: {light_hit.sum()} pixels, all see its emitting (front) side")

    # 2. round trip: the glTF content rendered by Mitsuba vs mitsuba.cornell_box()
    cm, persp = camera(g)
    to_world = cm @ np.diag([-1.0, 1.0, -1.0, 1.0])  # glTF camera frame -> Mitsuba sensor frame
    sensor = dict(ref["sensor"], fov_axis="y", fov=math.degrees(persp["yfov"]),
                  to_world=mi.ScalarTransform4f(to_world.tolist()))
    meshes = []
    for k, (name, mat, t, _) in enumerate(tris):
        mt = g["materials"][mat]
        rad = None
        if any(mt.get("emissiveFactor", [0, 0, 0])):
            s = mt.get("extensions", {}).get("KHR_materials_emissive_strength", {}).get("emissiveStrength", 1.0)
            rad = [c * s for c in mt["emissiveFactor"]]
        meshes.append((f"{name}-{k}", t.reshape(-1, 3), mt["pbrMetallicRoughness"]["baseColorFactor"][:3], rad))
    rt_scene = load_inline_scene(mi, ref["integrator"], sensor, meshes)
    a = np.array(mi.render(mi.load_dict(ref), spp=spp, seed=1))
    b = np.array(mi.render(rt_scene, spp=spp, seed=2))
    ma, mb = a.reshape(-1, 3).mean(0), b.reshape(-1, 3).mean(0)
    rel = np.abs(mb - ma) / ma
    fmt = lambda v, p=5: "[" + ", ".join(f"{x:.{p}f}" for x in v) + "]"
    print(f"round trip ({res}x{res}, {spp} spp, {variant}): mitsuba.cornell_box() mean {fmt(ma)}, "
          f"glTF in Mitsuba mean {fmt(mb)}, rel. diff {fmt(rel, 4)}")
    check(np.all(rel < 0.02), "round-trip mean radiance differs")


def load_inline_scene(mi, integrator, sensor, meshes):
    """Mitsuba scene from world-space triangle soups (meshes made in memory, no vertex normals,
    so Mitsuba's normal is the winding normal cross(p1 - p0, p2 - p0))."""
    d = {"type": "scene", "integrator": integrator, "sensor": sensor}
    for key, verts, albedo, rad in meshes:
        props = mi.Properties()
        props["bsdf"] = mi.load_dict({"type": "diffuse", "reflectance": {"type": "rgb", "value": albedo}})
        if rad is not None:
            props["emitter"] = mi.load_dict({"type": "area", "radiance": {"type": "rgb", "value": rad}})
        mesh = mi.Mesh(key, vertex_count=len(verts), face_count=len(verts) // 3, props=props,
                       has_vertex_normals=False)
        params = mi.traverse(mesh)
        # buffer types differ between variants (scalar: dr.scalar.ArrayXf, llvm: dr.llvm.Float)
        params["vertex_positions"] = type(params["vertex_positions"])(verts.reshape(-1).astype(np.float32))
        params["faces"] = type(params["faces"])(np.arange(len(verts), dtype=np.uint32))
        params.update()
        d[key] = mesh
    return mi.load_dict(d)


def main():
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    ap = argparse.ArgumentParser(description="validate the Cornell box glTF")
    ap.add_argument("scene", nargs="?", default=os.path.join(root, "scenes", "cornell-box", "scene.gltf"))
    ap.add_argument("--mitsuba", action="store_true", help="also compare with Mitsuba 3 renders")
    ap.add_argument("--variant", default="scalar_rgb")
    ap.add_argument("--resolution", type=int, default=128)
    ap.add_argument("--spp", type=int, default=64)
    args = ap.parse_args()
    try:
        g, data, tris, summary = structural(args.scene)
        print(f"structure OK: {summary}")
        if args.mitsuba:
            mitsuba_checks(g, tris, args.variant, args.resolution, args.spp)
    except Fail as e:
        print(f"FAIL: {e}")
        return 1
    print("OK")
    return 0


if __name__ == "__main__":
    sys.exit(main())
