#!/usr/bin/env python3
"""Writes the glass, clear-coat and sheen scene: scenes/glass-and-coats/.

Under the material preview's studio environment (../material-preview/studio.exr, by relative
URI) and a key light, on a grey Lambertian ground, every layer and transmitting BSDF of the
glTF extensions the renderer reads, each as a plain glTF material:

- "clear-glass" (front left): a solid glass sphere, KHR_materials_transmission 1 with
  KHR_materials_volume (thickness > 0: the sphere encloses glass) and a faint green
  attenuation, as window glass.
- "amber-glass" (front, second): a thick rounded block of tinted glass, its
  KHR_materials_volume attenuation colour reached after ATTENUATION_DISTANCE (Beer-Lambert:
  the longer a path inside, the deeper the colour).
- "frosted-glass" (back): an upright pane (a thin rounded slab, solid) of rough glass
  (roughnessFactor FROSTED_ROUGHNESS, GGX transmission), with an orange ball behind it seen
  blurred through it.
- "coated-paint" (front, third): a clear-coated neural material, car paint: the shipped code
  COATED_CODE of scenes/materials/latent.bin bound through the material extras
  {"neural": CODE}, under KHR_materials_clearcoat (factor 1, roughness COAT_ROUGHNESS).
  Without a latent file it renders as its glTF parameters (a blue metallic paint), still
  coated.
- "velvet" (front right): a sheen cloth, a sheet draped over a hidden ball with radial folds,
  KHR_materials_sheen (Charlie sheen) over a dark red diffuse-like base, double sided.

The spheres share one mesh's accessors (each glTF mesh names its material, the vertex data is
stored once), normals are the shapes' exact ones, and the buffer holds no texture coordinates
(nothing is textured), so the files stay small. Render:

    render scenes/glass-and-coats/scene.gltf --material scenes/materials/latent.bin -o out.png

Usage: python3 assets-scripts/make_glass_and_coats_scene.py [output-directory]
Needs numpy. Nothing is random: reruns write the same bytes.
"""

import argparse
import json
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from gltf_buffer import BufferWriter  # noqa: E402
import make_material_preview as preview  # noqa: E402

SPHERE_RADIUS = 0.3
SPHERE_SEGMENTS = (64, 32)  # longitude, latitude
BLOCK_HALF_SIZE = 0.22
BLOCK_EDGE_RADIUS = 0.05
BLOCK_YAW_DEGREES = 35.0
PANE_HALF_SIZE = (0.75, 0.5, 0.025)  # width, height, thickness
PANE_EDGE_RADIUS = 0.02
PANE_YAW_DEGREES = -8.0
PILLAR_SCALE = [0.45, 2.6, 0.45]  # of the block, for the pillars behind the pane
EDGE_SEGMENTS = 6  # quads across a rounded edge
CLOTH_HALF_SIZE = 0.5
CLOTH_CELLS = 48
CLOTH_HEIGHT = 0.42  # of the draped sheet's top above the ground
CLOTH_SHOULDER = 0.26  # radius at which the sheet starts to fall
CLOTH_FOLDS = 9  # around the ball
CLOTH_FOLD_DEPTH = 0.045
CLOTH_LIFT = 0.003  # above the ground where the sheet lies on it
COATED_CODE = "blue-metallic-paint"
COAT_ROUGHNESS = 0.05
FROSTED_ROUGHNESS = 0.35
ATTENUATION_COLOR = [0.95, 0.55, 0.12]
ATTENUATION_DISTANCE = 0.3
CAMERA_POSITION = [0.0, 1.1, 3.5]
CAMERA_TARGET = [0.0, 0.22, -0.25]
CAMERA_YFOV_DEGREES = 30.0
ASPECT_RATIO = 2.0
KEY_POSITION = [-1.6, 2.6, 1.8]
KEY_INTENSITY = 12.0  # W/sr
DEFAULT_SCENE_DIR = os.path.normpath(
    os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scenes", "glass-and-coats")
)


def yaw(degrees):
    """The quaternion (x, y, z, w) of a rotation by `degrees` about +y."""
    half = math.radians(degrees) / 2
    return [0.0, math.sin(half), 0.0, math.cos(half)]


def look_at_rotation(position, target):
    """The quaternion turning the camera's -z toward `target` with +y up (no roll)."""
    forward = np.subtract(target, position).astype(np.float64)
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    m = np.stack([right, up, -forward], axis=1)  # columns: the camera's x, y, z in the world
    w = math.sqrt(max(0.0, 1.0 + m[0, 0] + m[1, 1] + m[2, 2])) / 2
    x = (m[2, 1] - m[1, 2]) / (4 * w)
    y = (m[0, 2] - m[2, 0]) / (4 * w)
    z = (m[1, 0] - m[0, 1]) / (4 * w)
    return [float(x), float(y), float(z), float(w)]


def check_outward(positions, normals, triangles):
    """Every triangle winds counter-clockwise seen along its vertices' normals, and none is
    degenerate."""
    p = positions.astype(np.float64)
    a, b, c = p[triangles[:, 0]], p[triangles[:, 1]], p[triangles[:, 2]]
    face = np.cross(b - a, c - a)
    assert np.all(np.linalg.norm(face, axis=1) > 0.0), "degenerate triangle"
    n = normals[triangles].astype(np.float64).sum(axis=1)
    assert np.all(np.einsum("ij,ij->i", face, n) > 0.0), "a triangle winds inward"


def rounded_box(half, radius, segments):
    """Positions, normals and triangles of a box of half extents `half` whose edges and corners
    are rounded with `radius`: each face is a grid whose rows and columns crowd into the
    rounded edges (`segments` across each), its points pushed onto the rounded surface
    (p -> q + radius n with q = p clamped to the inner box, n = (p - q) / |p - q|). Vertices
    shared by two faces are merged, so the mesh is closed."""
    half = np.asarray(half, np.float64)
    inner = half - radius
    angles = np.linspace(0.0, np.pi / 2, segments + 1)

    def axis_coordinates(k):
        low = -inner[k] - radius * np.sin(angles[::-1])
        return np.concatenate([low, -low[::-1]])

    positions, triangles = [], []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            u_axis, v_axis = [(1, 2), (2, 0), (0, 1)][axis]
            if sign < 0:
                u_axis, v_axis = v_axis, u_axis  # keeps the winding outward
            us, vs = axis_coordinates(u_axis), axis_coordinates(v_axis)
            grid = np.zeros((len(vs), len(us), 3))
            grid[..., axis] = sign * half[axis]
            grid[..., u_axis] = us[None, :]
            grid[..., v_axis] = vs[:, None]
            base = sum(len(p) for p in positions)
            positions.append(grid.reshape(-1, 3))
            n_u = len(us)
            for j in range(len(vs) - 1):
                for i in range(n_u - 1):
                    a, b = base + j * n_u + i, base + j * n_u + i + 1
                    c, d = base + (j + 1) * n_u + i + 1, base + (j + 1) * n_u + i
                    triangles += [(a, b, c), (a, c, d)]
    flat = np.concatenate(positions)
    q = np.clip(flat, -inner, inner)
    normals = (flat - q) / np.linalg.norm(flat - q, axis=1, keepdims=True)
    points = q + radius * normals
    _, first, inverse = np.unique(np.round(points, 6), axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first)  # merged vertices in the order they were first made
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    keep = first[order]
    triangles = rank[inverse.reshape(-1)][np.asarray(triangles, np.int64)]
    return points[keep].astype(np.float32), normals[keep].astype(np.float32), triangles.astype(np.uint32)


def cloth_height(x, z):
    """Height of the draped sheet above the ground: a flat-topped bell over the hidden ball,
    folds around it where the sheet hangs, lying on the ground beyond."""
    r = np.hypot(x, z)
    theta = np.arctan2(z, x)
    bell = CLOTH_HEIGHT / (1.0 + (r / CLOTH_SHOULDER) ** 4)
    hanging = np.clip((r - 0.5 * CLOTH_SHOULDER) / CLOTH_SHOULDER, 0.0, 1.0)
    hanging = hanging * hanging * (3 - 2 * hanging) * np.clip(bell / (0.5 * CLOTH_HEIGHT), 0.0, 1.0)
    folds = CLOTH_FOLD_DEPTH * hanging * (np.sin(CLOTH_FOLDS * theta + 6.0 * r) + 0.5 * np.sin(4 * theta - 9.0 * r))
    return np.maximum(bell + folds, CLOTH_LIFT)


def cloth():
    """Positions, normals and triangles of the draped sheet (a height field over a square)."""
    s = np.linspace(-CLOTH_HALF_SIZE, CLOTH_HALF_SIZE, CLOTH_CELLS + 1)
    x, z = np.meshgrid(s, s)
    y = cloth_height(x, z)
    e = 1e-4
    dx = (cloth_height(x + e, z) - cloth_height(x - e, z)) / (2 * e)
    dz = (cloth_height(x, z + e) - cloth_height(x, z - e)) / (2 * e)
    normals = np.stack([-dx, np.ones_like(dx), -dz], axis=-1)
    normals /= np.linalg.norm(normals, axis=-1, keepdims=True)
    positions = np.stack([x, y, z], axis=-1).reshape(-1, 3)
    n = CLOTH_CELLS + 1
    triangles = []
    for j in range(CLOTH_CELLS):
        for i in range(CLOTH_CELLS):
            a, b, c, d = j * n + i, j * n + i + 1, (j + 1) * n + i + 1, (j + 1) * n + i
            triangles += [(a, d, c), (a, c, b)]
    return positions.astype(np.float32), normals.reshape(-1, 3).astype(np.float32), np.asarray(triangles, np.uint32)


def sphere():
    positions, normals, _uvs, triangles = preview.uv_sphere(SPHERE_RADIUS, *SPHERE_SEGMENTS)
    return positions, normals, triangles


def glass(name, roughness, volume):
    """A glass material: KHR_materials_transmission 1 on a white dielectric, solid
    (KHR_materials_volume)."""
    return {
        "name": name,
        "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0, "roughnessFactor": roughness},
        "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1.0}, "KHR_materials_volume": volume},
    }


MATERIALS = [
    glass("clear-glass", 0.0, {"thicknessFactor": 2 * SPHERE_RADIUS, "attenuationColor": [0.9, 0.97, 0.95], "attenuationDistance": 2.0}),
    glass("amber-glass", 0.0, {"thicknessFactor": 2 * BLOCK_HALF_SIZE, "attenuationColor": ATTENUATION_COLOR, "attenuationDistance": ATTENUATION_DISTANCE}),
    glass("frosted-glass", FROSTED_ROUGHNESS, {"thicknessFactor": 2 * PANE_HALF_SIZE[2]}),
    {
        "name": "coated-paint",
        "pbrMetallicRoughness": {"baseColorFactor": [0.05, 0.12, 0.45, 1.0], "metallicFactor": 0.6, "roughnessFactor": 0.35},
        "extensions": {"KHR_materials_clearcoat": {"clearcoatFactor": 1.0, "clearcoatRoughnessFactor": COAT_ROUGHNESS}},
        "extras": {"neural": COATED_CODE},
    },
    {
        "name": "velvet",
        "pbrMetallicRoughness": {"baseColorFactor": [0.22, 0.015, 0.05, 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0},
        "extensions": {"KHR_materials_sheen": {"sheenColorFactor": [1.0, 0.45, 0.55], "sheenRoughnessFactor": 0.45}},
        "doubleSided": True,
    },
    {
        "name": "orange",
        "pbrMetallicRoughness": {"baseColorFactor": [0.9, 0.3, 0.04, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.4},
    },
    {
        "name": "green",
        "pbrMetallicRoughness": {"baseColorFactor": [0.08, 0.5, 0.2, 1.0], "metallicFactor": 0.0, "roughnessFactor": 0.4},
    },
    {
        "name": "ground",
        "pbrMetallicRoughness": {"baseColorFactor": [preview.GROUND_ALBEDO] * 3 + [1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0},
        "extras": {"bsdf": "diffuse"},
    },
]


def build():
    buffer = BufferWriter()
    material = {m["name"]: i for i, m in enumerate(MATERIALS)}
    shapes = {
        "sphere": sphere(),
        "block": rounded_box([BLOCK_HALF_SIZE] * 3, BLOCK_EDGE_RADIUS, EDGE_SEGMENTS),
        "pane": rounded_box(PANE_HALF_SIZE, PANE_EDGE_RADIUS, EDGE_SEGMENTS),
        "cloth": cloth(),
    }
    primitives = {}
    for name, (positions, normals, triangles) in shapes.items():
        check_outward(positions, normals, triangles)
        primitives[name] = buffer.primitive({"POSITION": positions, "NORMAL": normals}, triangles, 0)
    ground_positions, ground_normals, _uvs, ground_triangles = preview.ground_quad(preview.GROUND_HALF_SIZE, 0.0)
    primitives["ground"] = buffer.primitive({"POSITION": ground_positions, "NORMAL": ground_normals}, ground_triangles, 0)

    r, b = SPHERE_RADIUS, BLOCK_HALF_SIZE
    # (node and mesh name, shape, material, translation, rotation, scale)
    objects = [
        ("clear-glass", "sphere", "clear-glass", [-0.98, r, 0.2], None, None),
        ("amber-glass", "block", "amber-glass", [-0.33, b, 0.35], yaw(BLOCK_YAW_DEGREES), None),
        ("coated-paint", "sphere", "coated-paint", [0.32, r, 0.25], None, None),
        ("velvet", "cloth", "velvet", [0.98, 0.0, 0.05], yaw(20.0), None),
        ("frosted-glass", "pane", "frosted-glass", [-0.15, PANE_HALF_SIZE[1], -0.75], yaw(PANE_YAW_DEGREES), None),
        ("orange-pillar", "block", "orange", [0.2, PILLAR_SCALE[1] * b, -1.05], None, PILLAR_SCALE),
        ("green-pillar", "block", "green", [-0.6, PILLAR_SCALE[1] * b * 0.9, -1.1], None, [PILLAR_SCALE[0], 0.9 * PILLAR_SCALE[1], PILLAR_SCALE[2]]),
        ("ground", "ground", "ground", None, None, None),
    ]
    meshes, nodes = [], []
    for name, shape, material_name, translation, rotation, scale in objects:
        meshes.append({"name": name, "primitives": [{**primitives[shape], "material": material[material_name]}]})
        node = {"name": name, "mesh": len(meshes) - 1}
        for key, value in (("translation", translation), ("rotation", rotation), ("scale", scale)):
            if value is not None:
                node[key] = value
        nodes.append(node)
    nodes += [
        {"name": "camera", "camera": 0, "translation": CAMERA_POSITION, "rotation": look_at_rotation(CAMERA_POSITION, CAMERA_TARGET)},
        {"name": "key-light", "translation": KEY_POSITION, "extensions": {"KHR_lights_punctual": {"light": 0}}},
    ]
    extensions = sorted({"KHR_lights_punctual"} | {e for m in MATERIALS for e in m.get("extensions", {})})
    gltf = {
        "asset": {"version": "2.0", "generator": "assets-scripts/make_glass_and_coats_scene.py"},
        "extensionsUsed": extensions,
        "scene": 0,
        "scenes": [{
            "name": "glass-and-coats",
            "nodes": list(range(len(nodes))),
            "extras": {"environment": {"image": "../material-preview/" + preview.ENVIRONMENT_IMAGE, "strength": preview.ENVIRONMENT_STRENGTH}},
        }],
        "nodes": nodes,
        "meshes": meshes,
        "materials": MATERIALS,
        "cameras": [{
            "name": "camera",
            "type": "perspective",
            "perspective": {"yfov": math.radians(CAMERA_YFOV_DEGREES), "aspectRatio": ASPECT_RATIO, "znear": 0.01, "zfar": 1000.0},
        }],
        "extensions": {"KHR_lights_punctual": {"lights": [{
            "name": "key", "type": "point", "color": preview.KEY_COLOR, "intensity": KEY_INTENSITY * preview.LUMENS_PER_WATT,
        }]}},
        **buffer.gltf_fields("scene.bin"),
    }
    return gltf, bytes(buffer.data)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("output", nargs="?", default=DEFAULT_SCENE_DIR, help="output directory")
    out_dir = os.path.normpath(parser.parse_args().output)
    os.makedirs(out_dir, exist_ok=True)
    gltf, data = build()
    with open(os.path.join(out_dir, "scene.bin"), "wb") as f:
        f.write(data)
    with open(os.path.join(out_dir, "scene.gltf"), "w") as f:
        json.dump(gltf, f, indent=1)
        f.write("\n")
    print(f"wrote {out_dir}/scene.gltf + scene.bin ({len(data)} bytes)")


if __name__ == "__main__":
    main()
