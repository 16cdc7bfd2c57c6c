#!/usr/bin/env python3
"""Write scenes/cornell-box/scene.gltf + scene.bin: Mitsuba 3's built-in Cornell box as glTF 2.0.

The scene is `mitsuba.cornell_box()` (the peer renderer's reference scene for rendering speed)
reproduced exactly. By default the script uses constants transcribed below from
`mitsuba.cornell_box()` of Mitsuba 3.9.1 (python/util.py), so it runs with nothing but the
Python standard library. `--from-mitsuba` reads the live dict from an installed Mitsuba instead,
and `--check-mitsuba` only verifies that the transcribed constants still match it.

Conventions of the output
-------------------------
* Shapes. Mitsuba's `rectangle` is the square [-1,1]^2 in the plane z = 0 with normal +z; its
  `cube` is [-1,1]^3 (24 vertices with flat, outward face normals, 12 triangles; the vertex and
  face lists below are Mitsuba's own cube mesh). Each glTF mesh keeps that canonical form and each
  shape's `to_world` becomes its node's `matrix` (column-major, as glTF requires). Every
  to_world here is a rotation times a positive scale (determinant > 0), so the node matrices keep
  the winding. Triangles are counter-clockwise seen from the side their normal points to (glTF's
  rule), and the stored normals equal that winding normal, which is also Mitsuba's normal.
  Node names are Mitsuba's shape ids ("floor", "ceiling", "back", "green-wall", "red-wall",
  "light", "small-box", "large-box").
  The to_world matrices are evaluated in float64 from the same translate/rotate/scale sequence
  Mitsuba uses, with entries below 1e-12 in magnitude set to 0 (Mitsuba evaluates them in
  float32, so its cos(90 deg) is -4.37e-8 instead of 0).
* Materials. All of Mitsuba's BSDFs here are `diffuse` (Lambert) with an RGB reflectance. Each
  becomes a pbrMetallicRoughness material with baseColorFactor = reflectance (linear RGB, alpha
  1), metallicFactor 0, roughnessFactor 1 and extras {"bsdf": "diffuse"}: the renderer reads that
  as a pure Lambertian BSDF with albedo baseColorFactor. Mitsuba's `diffuse` is one-sided: it
  reflects nothing on the back side of a surface (none of those is visible from the camera, but
  the light's upper face, 0.01 below the ceiling, is a back side). doubleSided is false.
* Emitter. The light rectangle (bsdf = white) is an `area` emitter; Mitsuba area emitters are
  one-sided, emitting only on the front side (the side of the normal, here straight down, -y).
  Its glTF material "light" is the white Lambert material plus emissiveFactor = radiance /
  max(radiance) and KHR_materials_emissive_strength.emissiveStrength = max(radiance), so
  emissiveFactor * emissiveStrength == Mitsuba's radiance. The triangle winding makes the
  geometric normal point down, so a renderer that treats emissive triangles as one-sided
  (emitting on the side of the winding normal) matches Mitsuba.
* Camera. Mitsuba's sensor to_world = look_at(origin, target, up) has columns
  (left, up', dir, origin) with dir = normalize(target - origin), left = normalize(up x dir),
  up' = dir x left; the sensor looks down its local +z, its local +x is the image's LEFT and +y
  is the image's up (its sample-to-camera transform scales x and y by -1/2). A glTF camera looks
  down its local -z with +x = image right and +y = image up. So the glTF node matrix has columns
  (-left, up', -dir, origin) = Mitsuba to_world * diag(-1, 1, -1, 1): both cameras see the same
  image, with the red wall (x = -1) on the left. For this scene that is the identity rotation
  with translation (0, 0, 3.9).
  Mitsuba's fov (degrees) applies to fov_axis; 'smaller' means x when width <= height, else y.
  glTF yfov = the vertical angle in radians: for the 256x256 film that is 39.3077 deg =
  0.686049 rad; aspectRatio = width / height = 1. znear 0.01, zfar 1e4. A renderer that keeps
  yfov fixed and takes the aspect from the output resolution matches Mitsuba with fov_axis 'y'
  (identical to 'smaller' for square and landscape images).
* Top-level scene extras: {"mitsuba_reference": "mitsuba.cornell_box()", "max_depth": 8, ...}.
  Mitsuba's path integrator counts max_depth in path vertices after the camera: 1 = emitters
  seen directly, 2 = direct lighting, 8 = up to 7 bounces; Russian roulette from depth 5
  (rr_depth default). The film is a 256x256 hdrfilm with a Gaussian reconstruction filter and
  64 spp, independent sampler.

Usage:
    python3 assets-scripts/make_cornell_box.py            # writes scenes/cornell-box/scene.{gltf,bin}
    python3 assets-scripts/make_cornell_box.py --from-mitsuba --variant scalar_rgb
    python3 assets-scripts/make_cornell_box.py --check-mitsuba
"""

import argparse
import json
import math
import os
import struct
import sys

MITSUBA_VERSION = "3.9.1"

# ---------------------------------------------------------------------------------------------
# Transcribed from mitsuba.cornell_box() of Mitsuba 3.9.1 (mitsuba/python/util.py).
# Transform ops are applied in the order written, as Mitsuba's chained ScalarTransform4f calls:
# T().translate(a).rotate(axis, deg).scale(s) == Translate(a) @ Rotate(axis, deg) @ Scale(s).
# ---------------------------------------------------------------------------------------------
MAX_DEPTH = 8
SENSOR = {
    "fov": 39.3077,  # degrees
    "fov_axis": "smaller",
    "near_clip": 0.001,
    "far_clip": 100.0,
    "origin": [0.0, 0.0, 3.90],
    "target": [0.0, 0.0, 0.0],
    "up": [0.0, 1.0, 0.0],
    "width": 256,
    "height": 256,
    "spp": 64,
    "rfilter": "gaussian",
}
BSDFS = {  # all 'diffuse' with an RGB reflectance
    "white": [0.885809, 0.698859, 0.666422],
    "green": [0.105421, 0.37798, 0.076425],
    "red": [0.570068, 0.0430135, 0.0443706],
}
LIGHT_RADIANCE = [18.387, 13.9873, 6.75357]  # 'area' emitter on the shape "light"
# (name, Mitsuba shape type, bsdf id, to_world ops, emitter?)
SHAPES = [
    ("light", "rectangle", "white",
     [("translate", [0.0, 0.99, 0.01]), ("rotate", [1, 0, 0], 90), ("scale", [0.23, 0.19, 0.19])], True),
    ("floor", "rectangle", "white",
     [("translate", [0.0, -1.0, 0.0]), ("rotate", [1, 0, 0], -90)], False),
    ("ceiling", "rectangle", "white",
     [("translate", [0.0, 1.0, 0.0]), ("rotate", [1, 0, 0], 90)], False),
    ("back", "rectangle", "white",
     [("translate", [0.0, 0.0, -1.0])], False),
    ("green-wall", "rectangle", "green",
     [("translate", [1.0, 0.0, 0.0]), ("rotate", [0, 1, 0], -90)], False),
    ("red-wall", "rectangle", "red",
     [("translate", [-1.0, 0.0, 0.0]), ("rotate", [0, 1, 0], 90)], False),
    ("small-box", "cube", "white",
     [("translate", [0.335, -0.7, 0.38]), ("rotate", [0, 1, 0], -17), ("scale", [0.3, 0.3, 0.3])], False),
    ("large-box", "cube", "white",
     [("translate", [-0.33, -0.4, -0.28]), ("rotate", [0, 1, 0], 18.25), ("scale", [0.3, 0.61, 0.3])], False),
]

# Mitsuba's canonical meshes.
RECT_POSITIONS = [(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)]
RECT_NORMALS = [(0, 0, 1)] * 4
RECT_INDICES = [0, 1, 2, 0, 2, 3]  # counter-clockwise seen from +z
# Mitsuba 3's `cube` mesh (src/shapes/cube.cpp), verbatim: 6 faces x 4 vertices.
CUBE_POSITIONS = [
    (1, -1, -1), (1, -1, 1), (-1, -1, 1), (-1, -1, -1),
    (1, 1, -1), (-1, 1, -1), (-1, 1, 1), (1, 1, 1),
    (1, -1, -1), (1, 1, -1), (1, 1, 1), (1, -1, 1),
    (1, -1, 1), (1, 1, 1), (-1, 1, 1), (-1, -1, 1),
    (-1, -1, 1), (-1, 1, 1), (-1, 1, -1), (-1, -1, -1),
    (1, 1, -1), (1, -1, -1), (-1, -1, -1), (-1, 1, -1),
]
CUBE_NORMALS = ([(0, -1, 0)] * 4 + [(0, 1, 0)] * 4 + [(1, 0, 0)] * 4 +
                [(0, 0, 1)] * 4 + [(-1, 0, 0)] * 4 + [(0, 0, -1)] * 4)
CUBE_INDICES = []
for _f in range(6):
    _b = 4 * _f
    CUBE_INDICES += [_b + 0, _b + 1, _b + 2, _b + 3, _b + 0, _b + 2]

# ------------------------------------------------------------------ small 4x4 / vector helpers


def mat_mul(a, b):
    return [[sum(a[i][k] * b[k][j] for k in range(4)) for j in range(4)] for i in range(4)]


def identity():
    return [[1.0 if i == j else 0.0 for j in range(4)] for i in range(4)]


def translate(v):
    m = identity()
    for i in range(3):
        m[i][3] = float(v[i])
    return m


def scale(v):
    m = identity()
    for i in range(3):
        m[i][i] = float(v[i])
    return m


def rotate(axis, deg):
    """Right-handed rotation about `axis` by `deg` degrees (Mitsuba's Transform4f::rotate)."""
    x, y, z = normalize(axis)
    a = math.radians(deg)
    c, s = math.cos(a), math.sin(a)
    t = 1.0 - c
    return [
        [t * x * x + c, t * x * y - s * z, t * x * z + s * y, 0.0],
        [t * x * y + s * z, t * y * y + c, t * y * z - s * x, 0.0],
        [t * x * z - s * y, t * y * z + s * x, t * z * z + c, 0.0],
        [0.0, 0.0, 0.0, 1.0],
    ]


def ops_to_matrix(ops):
    m = identity()
    for op in ops:
        if op[0] == "translate":
            m = mat_mul(m, translate(op[1]))
        elif op[0] == "rotate":
            m = mat_mul(m, rotate(op[1], op[2]))
        elif op[0] == "scale":
            m = mat_mul(m, scale(op[1]))
        else:
            raise ValueError(op)
    return clean(m)


def clean(m, eps=1e-12):
    return [[0.0 if abs(v) < eps else v for v in row] for row in m]


def sub(a, b):
    return [a[i] - b[i] for i in range(3)]


def cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def normalize(v):
    n = math.sqrt(sum(c * c for c in v))
    return [c / n for c in v]


def det3(m):
    return (m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]))


def column_major(m):
    """Row-major 4x4 (m[row][col]) -> glTF's 16-number column-major list."""
    return [m[r][c] for c in range(4) for r in range(4)]


def mitsuba_look_at(origin, target, up):
    """Mitsuba's Transform4f.look_at: columns (left, up', dir, origin)."""
    d = normalize(sub(target, origin))
    left = normalize(cross(up, d))
    new_up = cross(d, left)
    return [[left[i], new_up[i], d[i], origin[i]] for i in range(3)] + [[0.0, 0.0, 0.0, 1.0]]


def gltf_camera_matrix(origin, target, up):
    """glTF camera node matrix (row-major) seeing the same image as Mitsuba's look_at sensor.

    glTF camera: looks down local -z, +x = image right, +y = image up.
    Mitsuba sensor: looks down local +z, +x = image LEFT, +y = image up.
    => gltf = mitsuba_to_world @ diag(-1, 1, -1, 1), columns (-left, up', -dir, origin).
    """
    m = mitsuba_look_at(origin, target, up)
    return clean(mat_mul(m, scale([-1.0, 1.0, -1.0])))


def vertical_fov_deg(fov, fov_axis, width, height):
    """Mitsuba's (fov, fov_axis) -> vertical field of view in degrees for a width x height film."""
    aspect = width / height
    if fov_axis == "smaller":
        fov_axis = "y" if aspect > 1 else "x"
    elif fov_axis == "larger":
        fov_axis = "x" if aspect > 1 else "y"
    half = math.radians(fov) / 2
    if fov_axis == "y":
        return fov
    if fov_axis == "x":
        return math.degrees(2 * math.atan(math.tan(half) / aspect))
    if fov_axis == "diagonal":
        return math.degrees(2 * math.atan(math.tan(half) / math.sqrt(1 + aspect * aspect)))
    raise ValueError(fov_axis)


# --------------------------------------------------------------------- reading live Mitsuba


def find_libllvm():
    """Path of libLLVM.so.19* installed by Debian's libllvm19 (via dpkg -L), or None."""
    import glob
    import subprocess
    try:
        out = subprocess.run(["dpkg", "-L", "libllvm19"], capture_output=True, text=True,
                             check=False).stdout.split()
    except OSError:
        out = []
    cands = [p for p in out if "libLLVM" in os.path.basename(p) and ".so" in p]
    cands += sorted(glob.glob("/usr/lib/*/libLLVM.so.19*")) + sorted(glob.glob("/usr/lib/*/libLLVM-19.so*"))
    for p in cands:
        if os.path.isfile(p):
            return p
    return None


def import_mitsuba(variant):
    if variant.startswith("llvm") and "DRJIT_LIBLLVM_PATH" not in os.environ:
        p = find_libllvm()
        if p:
            os.environ["DRJIT_LIBLLVM_PATH"] = p
    import mitsuba as mi
    mi.set_variant(variant)
    return mi


def mitsuba_matrix(t):
    import numpy as np
    return [[float(v) for v in row] for row in np.array(t.matrix, dtype=np.float64)]


def read_mitsuba(variant):
    """Everything the glTF needs, read from the live mitsuba.cornell_box() dict."""
    mi = import_mitsuba(variant)
    d = mi.cornell_box()
    s = d["sensor"]
    sensor_m = mitsuba_matrix(s["to_world"])
    origin = [sensor_m[i][3] for i in range(3)]
    dirv = [sensor_m[i][2] for i in range(3)]
    upv = [sensor_m[i][1] for i in range(3)]
    sensor = dict(SENSOR)
    sensor.update(fov=float(s["fov"]), fov_axis=s["fov_axis"], near_clip=float(s["near_clip"]),
                  far_clip=float(s["far_clip"]), origin=origin,
                  target=[origin[i] + dirv[i] for i in range(3)], up=upv,
                  width=int(s["film"]["width"]), height=int(s["film"]["height"]),
                  spp=int(s["sampler"]["sample_count"]), rfilter=s["film"]["rfilter"]["type"])
    bsdfs, shapes, radiance = {}, [], None
    for k, v in d.items():
        if isinstance(v, dict) and v.get("type") == "diffuse":
            bsdfs[k] = [float(x) for x in v["reflectance"]["value"]]
    for k, v in d.items():
        if isinstance(v, dict) and v.get("type") in ("rectangle", "cube"):
            em = "emitter" in v
            if em:
                assert v["emitter"]["type"] == "area"
                radiance = [float(x) for x in v["emitter"]["radiance"]["value"]]
            shapes.append((k, v["type"], v["bsdf"]["id"], clean(mitsuba_matrix(v["to_world"]), 1e-6), em))
    return dict(version=mi.__version__, max_depth=int(d["integrator"]["max_depth"]), sensor=sensor,
                bsdfs=bsdfs, radiance=radiance, shapes=shapes)


def transcribed():
    return dict(version=MITSUBA_VERSION, max_depth=MAX_DEPTH, sensor=dict(SENSOR), bsdfs=dict(BSDFS),
                radiance=list(LIGHT_RADIANCE),
                shapes=[(n, t, b, ops_to_matrix(ops), e) for (n, t, b, ops, e) in SHAPES])


def check_against_mitsuba(variant, tol=1e-5):
    live, ours = read_mitsuba(variant), transcribed()
    problems = []

    def close(a, b):
        return all(abs(x - y) <= tol * max(1.0, abs(y)) for x, y in zip(a, b)) and len(a) == len(b)

    if live["max_depth"] != ours["max_depth"]:
        problems.append("max_depth")
    for k in ("fov", "near_clip", "far_clip"):
        if abs(live["sensor"][k] - ours["sensor"][k]) > tol:
            problems.append("sensor." + k)
    for k in ("fov_axis", "width", "height", "spp", "rfilter"):
        if live["sensor"][k] != ours["sensor"][k]:
            problems.append("sensor." + k)
    if not close(column_major(mitsuba_look_at(*(live["sensor"][k] for k in ("origin", "target", "up")))),
                 column_major(mitsuba_look_at(*(ours["sensor"][k] for k in ("origin", "target", "up"))))):
        problems.append("sensor.to_world")
    if set(live["bsdfs"]) != set(ours["bsdfs"]) or any(not close(live["bsdfs"][k], ours["bsdfs"][k])
                                                       for k in ours["bsdfs"]):
        problems.append("bsdfs")
    if not close(live["radiance"], ours["radiance"]):
        problems.append("radiance")
    lsh = {s[0]: s for s in live["shapes"]}
    if set(lsh) != {s[0] for s in ours["shapes"]}:
        problems.append("shape set")
    for n, t, b, m, e in ours["shapes"]:
        if n not in lsh:
            continue
        _, lt, lb, lm, le = lsh[n]
        if (lt, lb, le) != (t, b, e) or not close(column_major(lm), column_major(m)):
            problems.append("shape " + n)
    return live["version"], problems


# ------------------------------------------------------------------------------ glTF writing


class BinWriter:
    def __init__(self):
        self.data = bytearray()
        self.views, self.accessors = [], []

    def _view(self, payload, target):
        while len(self.data) % 4:
            self.data.append(0)
        self.views.append({"buffer": 0, "byteOffset": len(self.data), "byteLength": len(payload),
                           "target": target})
        self.data += payload
        return len(self.views) - 1

    def vec3(self, rows, with_bounds):
        payload = b"".join(struct.pack("<3f", *map(float, r)) for r in rows)
        acc = {"bufferView": self._view(payload, 34962), "componentType": 5126, "count": len(rows),
               "type": "VEC3"}
        if with_bounds:
            acc["min"] = [float(min(r[i] for r in rows)) for i in range(3)]
            acc["max"] = [float(max(r[i] for r in rows)) for i in range(3)]
        self.accessors.append(acc)
        return len(self.accessors) - 1

    def indices(self, idx):
        payload = struct.pack("<%dH" % len(idx), *idx)
        self.accessors.append({"bufferView": self._view(payload, 34963), "componentType": 5123,
                               "count": len(idx), "type": "SCALAR", "min": [min(idx)],
                               "max": [max(idx)]})
        return len(self.accessors) - 1


def build_gltf(sc, bin_name):
    w = BinWriter()
    geo = {
        "rectangle": {"POSITION": w.vec3(RECT_POSITIONS, True), "NORMAL": w.vec3(RECT_NORMALS, False),
                      "indices": w.indices(RECT_INDICES)},
        "cube": {"POSITION": w.vec3(CUBE_POSITIONS, True), "NORMAL": w.vec3(CUBE_NORMALS, False),
                 "indices": w.indices(CUBE_INDICES)},
    }

    materials, mat_index = [], {}

    def lambert(name, rgb):
        return {"name": name,
                "pbrMetallicRoughness": {"baseColorFactor": [float(c) for c in rgb] + [1.0],
                                         "metallicFactor": 0.0, "roughnessFactor": 1.0},
                "doubleSided": False,
                "extras": {"bsdf": "diffuse"}}

    for name in ("white", "red", "green"):
        mat_index[name] = len(materials)
        materials.append(lambert(name, sc["bsdfs"][name]))

    rad = sc["radiance"]
    strength = max(rad)
    light_bsdf = next(s[2] for s in sc["shapes"] if s[4])
    light = lambert("light", sc["bsdfs"][light_bsdf])
    light["emissiveFactor"] = [c / strength for c in rad]
    light["extensions"] = {"KHR_materials_emissive_strength": {"emissiveStrength": strength}}
    light["extras"].update({"emitter": "area", "one_sided": True, "mitsuba_radiance": rad})
    mat_index["light"] = len(materials)
    materials.append(light)

    meshes, mesh_index, nodes = [], {}, []
    for name, shape_type, bsdf, m, emitter in sc["shapes"]:
        mat = "light" if emitter else bsdf
        key = (shape_type, mat)
        if key not in mesh_index:
            g = geo[shape_type]
            mesh_index[key] = len(meshes)
            meshes.append({"name": f"{shape_type}-{mat}",
                           "primitives": [{"attributes": {"POSITION": g["POSITION"], "NORMAL": g["NORMAL"]},
                                           "indices": g["indices"], "material": mat_index[mat],
                                           "mode": 4}]})
        assert det3(m) > 0, f"{name}: to_world flips winding"
        nodes.append({"name": name, "mesh": mesh_index[key], "matrix": column_major(m),
                      "extras": {"mitsuba_type": shape_type}})

    s = sc["sensor"]
    yfov_deg = vertical_fov_deg(s["fov"], s["fov_axis"], s["width"], s["height"])
    cam_m = gltf_camera_matrix(s["origin"], s["target"], s["up"])
    cameras = [{"name": "camera", "type": "perspective",
                "perspective": {"yfov": math.radians(yfov_deg), "aspectRatio": s["width"] / s["height"],
                                "znear": 0.01, "zfar": 1.0e4}}]
    nodes.append({"name": "camera", "camera": 0, "matrix": column_major(cam_m),
                  "extras": {"mitsuba_fov_deg": s["fov"], "mitsuba_fov_axis": s["fov_axis"],
                             "look_at": {"origin": s["origin"], "target": s["target"], "up": s["up"]}}})

    gltf = {
        "asset": {"version": "2.0", "generator": "assets-scripts/make_cornell_box.py"},
        "extensionsUsed": ["KHR_materials_emissive_strength"],
        "scene": 0,
        "scenes": [{"name": "cornell-box", "nodes": list(range(len(nodes))),
                    "extras": {"mitsuba_reference": "mitsuba.cornell_box()",
                               "mitsuba_version": sc["version"],
                               "max_depth": sc["max_depth"],
                               "film": [s["width"], s["height"]], "spp": s["spp"],
                               "rfilter": s["rfilter"], "sampler": "independent"}}],
        "nodes": nodes,
        "meshes": meshes,
        "materials": materials,
        "cameras": cameras,
        "accessors": w.accessors,
        "bufferViews": w.views,
        "buffers": [{"uri": bin_name, "byteLength": len(w.data)}],
    }
    return gltf, bytes(w.data)


def main():
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--out-dir", default=os.path.join(root, "scenes", "cornell-box"))
    ap.add_argument("--from-mitsuba", action="store_true",
                    help="read mitsuba.cornell_box() from an installed Mitsuba instead of the constants")
    ap.add_argument("--check-mitsuba", action="store_true",
                    help="only compare the transcribed constants with the installed Mitsuba")
    ap.add_argument("--variant", default="scalar_rgb", help="Mitsuba variant for --from/--check-mitsuba")
    args = ap.parse_args()

    if args.check_mitsuba:
        version, problems = check_against_mitsuba(args.variant)
        if problems:
            print(f"MISMATCH with mitsuba {version}: {', '.join(problems)}")
            return 1
        print(f"transcribed constants match mitsuba.cornell_box() of mitsuba {version}")
        return 0

    sc = read_mitsuba(args.variant) if args.from_mitsuba else transcribed()
    os.makedirs(args.out_dir, exist_ok=True)
    gltf, data = build_gltf(sc, "scene.bin")
    with open(os.path.join(args.out_dir, "scene.bin"), "wb") as f:
        f.write(data)
    with open(os.path.join(args.out_dir, "scene.gltf"), "w") as f:
        json.dump(gltf, f, indent=1)
        f.write("\n")
    print(f"wrote {os.path.join(args.out_dir, 'scene.gltf')} + scene.bin ({len(data)} bytes) "
          f"from {'mitsuba ' + sc['version'] if args.from_mitsuba else 'constants of mitsuba ' + sc['version']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
