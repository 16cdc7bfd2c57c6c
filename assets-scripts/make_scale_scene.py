#!/usr/bin/env python3
"""Writes the scale test scene: a boulder field of ≥ 10 M triangle instances from ≥ 1 M unique
triangles, as glTF for our renderer and as PLY meshes + a `mi.load_dict` dictionary for
Mitsuba 3 (same geometry, same transforms, same lights). Default output: data/scale-scene/
(git-ignored; about 50 MB). Deterministic: numpy's default_rng(SEED), so a re-run writes the
same bytes (same numpy).

- "rock-00" .. "rock-49" (ROCK_MESHES unique meshes): a welded UV sphere of
  ROCK_LONGITUDE_SEGMENTS x ROCK_LATITUDE_BANDS (one vertex per pole, the pole bands as
  triangle fans: 2 x 160 x 63 = 20,160 triangles and 10,082 vertices a rock) whose radius in
  direction d is 1 + sum_k a_k sin(f_k (d . u_k) + phase_k) over ROCK_NOISE_TERMS random unit
  vectors u_k, frequencies f_k in ROCK_NOISE_FREQUENCY and amplitudes ROCK_NOISE_AMPLITUDE / k
  (a smooth, star-shaped lump), then squashed in y and stretched in x and z (ROCK_SQUASH_Y,
  ROCK_STRETCH_XZ). 50 x 20,160 = 1,008,000 unique triangles. Normals: area-weighted smooth
  vertex normals computed here and WRITTEN to both files (our loader would compute
  area-weighted normals itself; Mitsuba's PLY loader, without normals in the file, computes
  angle-weighted ones, which differ slightly: writing them makes both use the same data).
  Each rock mesh has one diffuse material of ROCK_ALBEDOS (cycled).
- ROCK_NODES_PER_MESH nodes per rock mesh ("rock-00-0" .., 500 in all, in shuffled order):
  uniform position over the FIELD_HALF_SIZE square, centre ROCK_CENTRE_HEIGHT x scale above the
  ground (the rock's bottom sinks into it), a random rotation about y and a uniform scale in
  ROCK_SCALE; written as the node's `matrix` (float32 values, column-major), which Mitsuba's
  instance gets verbatim as to_world. 500 x 20,160 = 10,080,000 triangle instances. Our loader
  stores each rock once (two-level BVH: a mesh whose copies would store ≥ 1024 extra triangles).
- "ground": a GROUND_HALF_SIZE square at y = 0 (2 triangles, normals +y), diffuse GROUND_ALBEDO.
- Materials: baseColorFactor = the albedo, metallic 0, roughness 1, extras {"bsdf": "diffuse"}
  (our Lambert), which Mitsuba's `diffuse` matches exactly.
- "camera": perspective, yfov CAMERA_YFOV_DEGREES, aspectRatio CAMERA_ASPECT (16:9), at
  CAMERA_POSITION looking at CAMERA_TARGET (its node matrix: columns right, up, back; the
  horizon is inside the frame's top, so the sky shows).
- "sun": KHR_lights_punctual directional, SUN_IRRADIANCE W/m^2 written in lux (x 683 lm/W =
  2049 lx), travelling along SUN_DIRECTION (the node's -z).
- The environment, in the scene's extras: {"environment": {"color": ENVIRONMENT_COLOR}}.

Files: scene.gltf + scene.bin (POSITION float32 with min/max, NORMAL float32, indices uint32;
no texture coordinates), and for Mitsuba one binary little-endian PLY per mesh, MESH-NAME.ply
("vertex": float x y z nx ny nz; "face": list uchar uint vertex_indices), with the same arrays.

`mitsuba_scene(scene_dir, width, height, spp, max_depth, shapes=None)` reads scene.gltf (so the
transforms are exactly the file's float32 values) and returns the `mi.load_dict` dictionary
(call `mi.set_variant` first):
- a mesh used by several nodes becomes a `shapegroup` holding its `ply` shape, and each node an
  `instance` with to_world = the node's world matrix; a mesh used once (the ground) a `ply`
  shape with that to_world. `shapes` may map mesh names to already loaded shapes (e.g. from
  `mitsuba_mesh_dicts`), so that a caller can time reading the PLYs apart from building the scene;
- `diffuse` BSDFs with reflectance = the material's baseColorFactor rgb;
- the sun as `directional` with irradiance intensity / 683 x colour (W/m^2, as our loader
  converts) along the node's -z; `constant` emitter with radiance = the environment colour;
- a `perspective` sensor, fov_axis "y", fov = yfov, to_world = the camera node's matrix times
  diag(-1, 1, -1) (Mitsuba's camera looks along +z with +x to the image left; glTF's along -z
  with +x to the right), `hdrfilm` width x height with a `box` filter (ours averages uniformly
  jittered samples per pixel), `independent` sampler with spp samples;
- integrator `path` with max_depth (our --max-depth has Mitsuba's meaning).

Usage: python3 assets-scripts/make_scale_scene.py [OUTPUT_DIR]     # default data/scale-scene
Needs numpy only (mitsuba_scene also needs Mitsuba 3, imported only when it is called).
"""

import argparse
import json
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from gltf_buffer import ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER, FLOAT, UNSIGNED_INT, BufferWriter  # noqa: E402
from make_material_preview import LUMENS_PER_WATT, _mitsuba  # noqa: E402

SEED = 20240611
ROCK_MESHES = 50
ROCK_NODES_PER_MESH = 10
ROCK_LONGITUDE_SEGMENTS = 160
ROCK_LATITUDE_BANDS = 64
ROCK_NOISE_TERMS = 6
ROCK_NOISE_AMPLITUDE = 0.12  # of the first term; term k has ROCK_NOISE_AMPLITUDE / k
ROCK_NOISE_FREQUENCY = (1.5, 5.0)  # radians per unit of d . u
ROCK_SQUASH_Y = (0.55, 0.85)
ROCK_STRETCH_XZ = (0.85, 1.2)
ROCK_SCALE = (0.5, 1.5)
ROCK_CENTRE_HEIGHT = 0.2  # x the instance's scale, above the ground
ROCK_ALBEDOS = [
    [0.42, 0.40, 0.37],
    [0.35, 0.35, 0.35],
    [0.50, 0.45, 0.38],
    [0.30, 0.29, 0.27],
    [0.46, 0.43, 0.42],
]
FIELD_HALF_SIZE = 25.0
GROUND_HALF_SIZE = 500.0
GROUND_ALBEDO = [0.30, 0.27, 0.22]
CAMERA_POSITION = [0.0, 9.0, 34.0]
CAMERA_TARGET = [0.0, 0.0, 2.0]
CAMERA_YFOV_DEGREES = 40.0
CAMERA_ASPECT = 16.0 / 9.0
CAMERA_ZNEAR = 0.05
CAMERA_ZFAR = 5000.0
SUN_IRRADIANCE = 3.0  # W/m^2, written as SUN_IRRADIANCE x 683 = 2049 lx
SUN_DIRECTION = [0.45, -0.57, -0.69]  # of travel (normalised below): from the front left, above
ENVIRONMENT_COLOR = [0.3, 0.35, 0.4]
MIN_UNIQUE_TRIANGLES = 1_000_000
MIN_TRIANGLE_INSTANCES = 10_000_000
DEFAULT_SCENE_DIR = os.path.normpath(
    os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "data", "scale-scene")
)


def normalize(v):
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def welded_sphere(n_lon, n_lat):
    """Unit directions (float64) and CCW-outward triangles (uint32) of a UV sphere with one
    vertex per pole and n_lat - 1 rings of n_lon vertices (no seam duplicates)."""
    theta = np.pi * np.arange(1, n_lat) / n_lat
    phi = 2.0 * np.pi * np.arange(n_lon) / n_lon
    t, p = np.meshgrid(theta, phi, indexing="ij")  # ring j, segment i
    rings = np.stack([np.sin(t) * np.cos(p), np.cos(t), -np.sin(t) * np.sin(p)], -1).reshape(-1, 3)
    directions = np.concatenate([[[0.0, 1.0, 0.0]], rings, [[0.0, -1.0, 0.0]]])
    south = len(directions) - 1
    i = np.arange(n_lon)
    i1 = (i + 1) % n_lon

    def ring(j, k):  # vertex k of ring j (j = 0 .. n_lat - 2)
        return 1 + j * n_lon + k

    top = np.stack([np.zeros(n_lon, int), ring(0, i), ring(0, i1)], -1)
    bottom = np.stack([np.full(n_lon, south), ring(n_lat - 2, i1), ring(n_lat - 2, i)], -1)
    j = np.arange(n_lat - 2)[:, None]
    a, b = ring(j, i), ring(j, i1)  # upper ring
    c, d = ring(j + 1, i1), ring(j + 1, i)  # lower ring
    bands = np.concatenate(
        [np.stack([a, d, c], -1).reshape(-1, 3), np.stack([a, c, b], -1).reshape(-1, 3)]
    )
    triangles = np.concatenate([top, bands, bottom]).astype(np.uint32)
    return directions, triangles


def face_normals(positions, triangles):
    """Unnormalised face normals (twice the area), float64."""
    p = positions.astype(np.float64)
    a, b, c = p[triangles[:, 0]], p[triangles[:, 1]], p[triangles[:, 2]]
    return np.cross(b - a, c - a)


def vertex_normals(positions, triangles):
    """Area-weighted smooth vertex normals (float32), as our loader computes without NORMAL."""
    faces = face_normals(positions, triangles)
    sums = np.zeros((len(positions), 3))
    for corner in range(3):
        np.add.at(sums, triangles[:, corner], faces)
    return normalize(sums).astype(np.float32)


def check_outward(positions, triangles, centre):
    faces = face_normals(positions, triangles)
    centroid = positions.astype(np.float64)[triangles].mean(axis=1) - centre
    assert np.all(np.einsum("ij,ij->i", faces, centroid) > 0.0), "winding is not outward"
    assert np.all(np.linalg.norm(faces, axis=1) > 0.0), "degenerate triangle"


def rock_mesh(rng, directions, triangles):
    """Positions and normals (float32) of one rock: the sphere displaced by smooth noise."""
    radius = np.ones(len(directions))
    for k in range(1, ROCK_NOISE_TERMS + 1):
        u = normalize(rng.normal(size=3))
        f = rng.uniform(*ROCK_NOISE_FREQUENCY)
        phase = rng.uniform(0.0, 2.0 * np.pi)
        radius += ROCK_NOISE_AMPLITUDE / k * np.sin(f * directions @ u + phase)
    stretch = np.array(
        [rng.uniform(*ROCK_STRETCH_XZ), rng.uniform(*ROCK_SQUASH_Y), rng.uniform(*ROCK_STRETCH_XZ)]
    )
    positions = (directions * radius[:, None] * stretch).astype(np.float32)
    check_outward(positions, triangles, np.zeros(3))  # star-shaped about the origin
    return positions, vertex_normals(positions, triangles)


def rock_placements(rng):
    """[(mesh index, 4x4 float32 world matrix)]: ROCK_NODES_PER_MESH nodes per mesh, shuffled."""
    meshes = rng.permutation(np.repeat(np.arange(ROCK_MESHES), ROCK_NODES_PER_MESH))
    placements = []
    for mesh in meshes:
        x, z = rng.uniform(-FIELD_HALF_SIZE, FIELD_HALF_SIZE, size=2)
        angle = rng.uniform(0.0, 2.0 * np.pi)
        scale = rng.uniform(*ROCK_SCALE)
        c, s = math.cos(angle), math.sin(angle)
        m = np.eye(4)
        m[:3, :3] = scale * np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
        m[:3, 3] = [x, ROCK_CENTRE_HEIGHT * scale, z]
        placements.append((int(mesh), m.astype(np.float32)))
    return placements


def look_at_matrix(eye, target, up=(0.0, 1.0, 0.0)):
    """glTF camera node matrix (float32): -z toward target, +y up, +x right."""
    f = normalize(np.subtract(target, eye))
    right = normalize(np.cross(f, up))
    m = np.eye(4)
    m[:3, :3] = np.stack([right, np.cross(right, f), -f], axis=1)
    m[:3, 3] = eye
    return m.astype(np.float32)


def direction_matrix(direction):
    """A rotation (float32 4x4) turning -z onto `direction` (for the sun's node)."""
    f = normalize(direction)
    up = (0.0, 0.0, 1.0) if abs(f[1]) > 0.99 else (0.0, 1.0, 0.0)
    m = look_at_matrix(np.zeros(3), f, up)
    m[:3, 3] = 0.0
    return m


def gltf_matrix(m):
    """A 4x4 matrix as glTF's column-major list (the float32 values, exactly)."""
    return [float(v) for v in np.asarray(m, np.float32).T.reshape(-1)]


def ground_quad():
    h = GROUND_HALF_SIZE
    positions = np.array([[-h, 0.0, h], [h, 0.0, h], [h, 0.0, -h], [-h, 0.0, -h]], np.float32)
    normals = np.tile(np.array([0.0, 1.0, 0.0], np.float32), (4, 1))
    triangles = np.array([[0, 1, 2], [0, 2, 3]], np.uint32)
    check_outward(positions, triangles, np.array([0.0, -1.0, 0.0]))
    return positions, normals, triangles


def ply_bytes(positions, normals, triangles):
    """Binary little-endian PLY: vertex float x y z nx ny nz, face list uchar uint."""
    header = (
        "ply\nformat binary_little_endian 1.0\ncomment assets-scripts/make_scale_scene.py\n"
        f"element vertex {len(positions)}\n"
        + "".join(f"property float {c}\n" for c in ("x", "y", "z", "nx", "ny", "nz"))
        + f"element face {len(triangles)}\nproperty list uchar uint vertex_indices\nend_header\n"
    )
    vertices = np.concatenate([positions, normals], axis=1).astype("<f4")
    faces = np.zeros(len(triangles), dtype=[("n", "u1"), ("v", "<u4", 3)])
    faces["n"], faces["v"] = 3, triangles
    return header.encode("ascii") + vertices.tobytes() + faces.tobytes()


def diffuse_material(name, albedo):
    return {
        "name": name,
        "pbrMetallicRoughness": {
            "baseColorFactor": [float(a) for a in albedo] + [1.0],
            "metallicFactor": 0.0,
            "roughnessFactor": 1.0,
        },
        "extras": {"bsdf": "diffuse"},
    }


def primitive(buffer, positions, normals, triangles, material):
    """POSITION, NORMAL and uint32 indices (BufferWriter.primitive would write u16 ones)."""
    return {
        "attributes": {
            "POSITION": buffer.add(positions.astype("<f4"), FLOAT, "VEC3", ARRAY_BUFFER, True),
            "NORMAL": buffer.add(normals.astype("<f4"), FLOAT, "VEC3", ARRAY_BUFFER),
        },
        "indices": buffer.add(
            triangles.reshape(-1).astype("<u4"), UNSIGNED_INT, "SCALAR", ELEMENT_ARRAY_BUFFER
        ),
        "material": material,
        "mode": 4,
    }


def build():
    """(glTF dict, scene.bin bytes, {PLY file name: bytes})."""
    rng = np.random.default_rng(SEED)
    buffer = BufferWriter()
    directions, triangles = welded_sphere(ROCK_LONGITUDE_SEGMENTS, ROCK_LATITUDE_BANDS)
    check_outward(directions, triangles, np.zeros(3))
    materials = [diffuse_material(f"rock-{i}", a) for i, a in enumerate(ROCK_ALBEDOS)]
    materials.append(diffuse_material("ground", GROUND_ALBEDO))
    meshes, plys = [], {}
    for r in range(ROCK_MESHES):
        positions, normals = rock_mesh(rng, directions, triangles)
        name = f"rock-{r:02d}"
        material = r % len(ROCK_ALBEDOS)
        meshes.append({"name": name, "primitives": [primitive(buffer, positions, normals, triangles, material)]})
        plys[f"{name}.ply"] = ply_bytes(positions, normals, triangles)
    ground = ground_quad()
    meshes.append({"name": "ground", "primitives": [primitive(buffer, *ground, len(materials) - 1)]})
    plys["ground.ply"] = ply_bytes(*ground)

    copies = {}
    nodes = []
    for mesh, matrix in rock_placements(rng):
        copy = copies[mesh] = copies.get(mesh, -1) + 1
        nodes.append({"name": f"rock-{mesh:02d}-{copy}", "mesh": mesh, "matrix": gltf_matrix(matrix)})
    nodes.append({"name": "ground", "mesh": ROCK_MESHES})
    nodes.append({"name": "camera", "camera": 0, "matrix": gltf_matrix(look_at_matrix(CAMERA_POSITION, CAMERA_TARGET))})
    nodes.append(
        {
            "name": "sun",
            "matrix": gltf_matrix(direction_matrix(SUN_DIRECTION)),
            "extensions": {"KHR_lights_punctual": {"light": 0}},
        }
    )
    gltf = {
        "asset": {"version": "2.0", "generator": "assets-scripts/make_scale_scene.py"},
        "extensionsUsed": ["KHR_lights_punctual"],
        "scene": 0,
        "scenes": [
            {
                "name": "scale-scene",
                "nodes": list(range(len(nodes))),
                "extras": {"environment": {"color": ENVIRONMENT_COLOR}},
            }
        ],
        "nodes": nodes,
        "meshes": meshes,
        "materials": materials,
        "cameras": [
            {
                "name": "camera",
                "type": "perspective",
                "perspective": {
                    "yfov": math.radians(CAMERA_YFOV_DEGREES),
                    "aspectRatio": CAMERA_ASPECT,
                    "znear": CAMERA_ZNEAR,
                    "zfar": CAMERA_ZFAR,
                },
            }
        ],
        "extensions": {
            "KHR_lights_punctual": {
                "lights": [
                    {
                        "name": "sun",
                        "type": "directional",
                        "color": [1.0, 1.0, 1.0],
                        "intensity": SUN_IRRADIANCE * LUMENS_PER_WATT,
                    }
                ]
            }
        },
        **buffer.gltf_fields("scene.bin"),
    }
    return gltf, bytes(buffer.data), plys


# ------------------------------------------------------------------------- reading it back


def load_gltf(scene_dir):
    with open(os.path.join(scene_dir, "scene.gltf")) as f:
        return json.load(f)


def node_matrix(node):
    """The node's local matrix as a float64 4x4 (rows = output axes); these scenes are flat."""
    if "matrix" in node:
        return np.array(node["matrix"], np.float64).reshape(4, 4).T
    assert not any(k in node for k in ("translation", "rotation", "scale", "children"))
    return np.eye(4)


def triangle_counts(gltf):
    """(unique triangles, triangle instances) of the file's mesh nodes."""
    per_mesh = [
        sum(gltf["accessors"][p["indices"]]["count"] // 3 for p in m["primitives"])
        for m in gltf["meshes"]
    ]
    instances = sum(per_mesh[n["mesh"]] for n in gltf["nodes"] if "mesh" in n)
    return sum(per_mesh), instances


# ---------------------------------------------------------------------------------- Mitsuba 3


def mitsuba_mesh_dicts(scene_dir, gltf=None):
    """{mesh name: `ply` shape dictionary with its `diffuse` BSDF} for every glTF mesh."""
    gltf = gltf or load_gltf(scene_dir)
    shapes = {}
    for mesh in gltf["meshes"]:
        (prim,) = mesh["primitives"]
        albedo = gltf["materials"][prim["material"]]["pbrMetallicRoughness"]["baseColorFactor"][:3]
        shapes[mesh["name"]] = {
            "type": "ply",
            "filename": os.path.join(scene_dir, f"{mesh['name']}.ply"),
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": albedo}},
        }
    return shapes


def mitsuba_scene(scene_dir=DEFAULT_SCENE_DIR, width=640, height=360, spp=16, max_depth=8, shapes=None):
    """The scene as a `mi.load_dict` dictionary, read from scene_dir/scene.gltf (see the module
    docstring for the correspondence). `shapes`: {mesh name: dictionary or loaded mi.Shape},
    default `mitsuba_mesh_dicts(scene_dir)`."""
    mi = _mitsuba()
    gltf = load_gltf(scene_dir)
    shapes = shapes or mitsuba_mesh_dicts(scene_dir, gltf)
    uses = {}
    for node in gltf["nodes"]:
        if "mesh" in node:
            uses[node["mesh"]] = uses.get(node["mesh"], 0) + 1
    scene = {"type": "scene", "integrator": {"type": "path", "max_depth": int(max_depth)}}
    for index, mesh in enumerate(gltf["meshes"]):
        if uses.get(index, 0) > 1:
            scene[f"group-{mesh['name']}"] = {"type": "shapegroup", mesh["name"]: shapes[mesh["name"]]}
    (light,) = gltf["extensions"]["KHR_lights_punctual"]["lights"]
    assert light["type"] == "directional"
    for node in gltf["nodes"]:
        world = node_matrix(node)
        to_world = mi.ScalarTransform4f(world.tolist())
        if "mesh" in node:
            mesh = gltf["meshes"][node["mesh"]]
            if uses[node["mesh"]] > 1:
                scene[node["name"]] = {
                    "type": "instance",
                    "to_world": to_world,
                    "shapegroup": {"type": "ref", "id": f"group-{mesh['name']}"},
                }
            else:
                shape = shapes[mesh["name"]]
                if isinstance(shape, dict):
                    shape = dict(shape, to_world=to_world)
                else:
                    assert np.array_equal(world, np.eye(4)), "a loaded shape cannot be moved"
                scene[node["name"]] = shape
        elif "camera" in node:
            camera = gltf["cameras"][node["camera"]]["perspective"]
            scene["sensor"] = {
                "type": "perspective",
                "fov_axis": "y",
                "fov": math.degrees(camera["yfov"]),
                "near_clip": camera["znear"],
                "far_clip": camera.get("zfar", 1e4),
                "to_world": mi.ScalarTransform4f((world @ np.diag([-1.0, 1.0, -1.0, 1.0])).tolist()),
                "sampler": {"type": "independent", "sample_count": int(spp)},
                "film": {
                    "type": "hdrfilm",
                    "width": int(width),
                    "height": int(height),
                    "pixel_format": "rgb",
                    "rfilter": {"type": "box"},
                },
            }
        elif "extensions" in node:
            direction = normalize(world[:3, :3] @ [0.0, 0.0, -1.0])
            irradiance = [light["intensity"] / LUMENS_PER_WATT * c for c in light["color"]]
            scene[node["name"]] = {
                "type": "directional",
                "direction": [float(v) for v in direction],
                "irradiance": {"type": "rgb", "value": irradiance},
            }
    environment = gltf["scenes"][0]["extras"]["environment"]["color"]
    scene["environment"] = {"type": "constant", "radiance": {"type": "rgb", "value": environment}}
    return scene


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("output", nargs="?", default=DEFAULT_SCENE_DIR, help="output directory")
    out_dir = os.path.normpath(parser.parse_args().output)
    os.makedirs(out_dir, exist_ok=True)
    gltf, data, plys = build()
    unique, instances = triangle_counts(gltf)
    assert unique >= MIN_UNIQUE_TRIANGLES and instances >= MIN_TRIANGLE_INSTANCES, (unique, instances)
    for name, content in plys.items():
        with open(os.path.join(out_dir, name), "wb") as f:
            f.write(content)
    with open(os.path.join(out_dir, "scene.bin"), "wb") as f:
        f.write(data)
    with open(os.path.join(out_dir, "scene.gltf"), "w") as f:
        json.dump(gltf, f, indent=1)
        f.write("\n")
    mesh_nodes = sum("mesh" in n for n in gltf["nodes"])
    print(
        f"wrote {out_dir}: scene.gltf + scene.bin ({len(data)} bytes) and {len(plys)} PLY files "
        f"({sum(len(c) for c in plys.values())} bytes): {len(gltf['meshes'])} meshes, "
        f"{mesh_nodes} mesh nodes, {unique:,} unique triangles, {instances:,} triangle instances"
    )


if __name__ == "__main__":
    main()
