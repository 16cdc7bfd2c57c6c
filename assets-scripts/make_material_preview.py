#!/usr/bin/env python3
"""Writes the material-preview scene: scenes/material-preview/scene.gltf + scene.bin.

The scene follows the NBRDF authors' sample scene (a sphere under an environment map, camera
at distance 2, vertical field of view 30 degrees), which the evaluation renders with decoded
and tabulated BRDFs:

- "sphere": a UV sphere of radius SPHERE_RADIUS at the origin (LONGITUDE_SEGMENTS x
  LATITUDE_SEGMENTS quads, the pole rows as single triangles), analytic smooth normals and
  texture coordinates (u increasing to the right seen from the camera, the seam at the back,
  v = 0 at the top, glTF's convention). Its material is named "preview": it binds the latent
  code "alum-bronze" (extras {"neural": "alum-bronze"}) when the renderer is given a latent
  file (`render ... --material scenes/materials/latent.bin`), and otherwise renders as its
  copper-like metallic-roughness parameters; `--bind preview=SPEC` rebinds it.
  With the camera at distance 2 and yfov 30 deg, radius 0.37 makes the sphere's silhouette
  span about 70 % of the frame height: tan(asin(0.37 / 2)) / tan(15 deg) = 0.70.
- "ground": a 100 x 100 quad touching the sphere's bottom (y = -SPHERE_RADIUS), neutral grey
  Lambert (material extras {"bsdf": "diffuse"}).
- "camera": perspective, yfov 30 deg, aspect ratio 1, at distance 2 from the sphere's centre,
  raised CAMERA_ELEVATION_DEGREES above the horizontal, looking at the centre.
- "key": a KHR_lights_punctual point light above-left of and in front of the sphere
  (radiometric intensity in W/sr, as the renderer reads it).
- The environment, named in the scene's extras: studio.exr next to the scene file (made by
  make_studio_envmap.py).

Usage: python3 assets-scripts/make_material_preview.py [output-directory]
Needs numpy only.
"""

import json
import math
import os
import struct
import sys

import numpy as np

SPHERE_RADIUS = 0.37
LONGITUDE_SEGMENTS = 128
LATITUDE_SEGMENTS = 64
CAMERA_DISTANCE = 2.0
CAMERA_YFOV_DEGREES = 30.0
CAMERA_ELEVATION_DEGREES = 10.0
GROUND_HALF_SIZE = 50.0
GROUND_ALBEDO = 0.5
KEY_POSITION = [-1.5, 2.0, 1.5]
KEY_COLOR = [1.0, 0.92, 0.82]
KEY_INTENSITY = 10.0
PREVIEW_BASE_COLOR = [0.955, 0.638, 0.538, 1.0]  # copper's linear F0
PREVIEW_ROUGHNESS = 0.3

FLOAT, UNSIGNED_SHORT, UNSIGNED_INT = 5126, 5123, 5125
ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963


def uv_sphere(radius, n_lon, n_lat):
    """Positions, normals, uvs (float32) and CCW-outward triangles (uint32) of a UV sphere."""
    u = np.linspace(0.0, 1.0, n_lon + 1)
    v = np.linspace(0.0, 1.0, n_lat + 1)
    uu, vv = np.meshgrid(u, v)  # row j = latitude ring j, from the top
    theta, phi = np.pi * vv, 2.0 * np.pi * uu
    normals = np.stack(
        [-np.sin(theta) * np.sin(phi), np.cos(theta), -np.sin(theta) * np.cos(phi)], axis=-1
    ).reshape(-1, 3)
    positions = radius * normals
    uvs = np.stack([uu, vv], axis=-1).reshape(-1, 2)

    def vertex(i, j):
        return j * (n_lon + 1) + i

    triangles = []
    for j in range(n_lat):
        for i in range(n_lon):
            a, b = vertex(i, j), vertex(i + 1, j)
            c, d = vertex(i + 1, j + 1), vertex(i, j + 1)
            if j != 0:
                triangles.append((a, d, b))
            if j != n_lat - 1:
                triangles.append((b, d, c))
    triangles = np.asarray(triangles, dtype=np.uint32)
    return (
        positions.astype(np.float32),
        normals.astype(np.float32),
        uvs.astype(np.float32),
        triangles,
    )


def check_outward(positions, triangles):
    p = positions.astype(np.float64)
    a, b, c = p[triangles[:, 0]], p[triangles[:, 1]], p[triangles[:, 2]]
    face = np.cross(b - a, c - a)
    centroid = (a + b + c) / 3.0
    assert np.all(np.einsum("ij,ij->i", face, centroid) > 0.0), "sphere winding is inward"
    assert np.all(np.linalg.norm(face, axis=1) > 0.0), "degenerate sphere triangle"


def ground_quad(half, y):
    positions = np.array(
        [[-half, y, half], [half, y, half], [half, y, -half], [-half, y, -half]], np.float32
    )
    normals = np.tile(np.array([0.0, 1.0, 0.0], np.float32), (4, 1))
    uvs = np.array([[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]], np.float32)
    triangles = np.array([[0, 1, 2], [0, 2, 3]], np.uint32)
    check_outward(positions - np.array([0.0, y - 1.0, 0.0], np.float32), triangles)
    return positions, normals, uvs, triangles


class BufferWriter:
    """One binary buffer with its buffer views and accessors, 4-byte aligned."""

    def __init__(self):
        self.data = bytearray()
        self.views = []
        self.accessors = []

    def add(self, array, component_type, accessor_type, target, bounds=False):
        while len(self.data) % 4:
            self.data.append(0)
        raw = np.ascontiguousarray(array).tobytes()
        self.views.append(
            {"buffer": 0, "byteOffset": len(self.data), "byteLength": len(raw), "target": target}
        )
        self.data.extend(raw)
        accessor = {
            "bufferView": len(self.views) - 1,
            "componentType": component_type,
            "count": int(array.shape[0]),
            "type": accessor_type,
        }
        if bounds:
            accessor["min"] = [float(x) for x in array.min(axis=0)]
            accessor["max"] = [float(x) for x in array.max(axis=0)]
        self.accessors.append(accessor)
        return len(self.accessors) - 1

    def mesh_primitive(self, positions, normals, uvs, triangles, material):
        flat = triangles.reshape(-1)
        if positions.shape[0] <= 0xFFFF:
            indices = self.add(flat.astype("<u2"), UNSIGNED_SHORT, "SCALAR", ELEMENT_ARRAY_BUFFER)
        else:
            indices = self.add(flat.astype("<u4"), UNSIGNED_INT, "SCALAR", ELEMENT_ARRAY_BUFFER)
        return {
            "attributes": {
                "POSITION": self.add(positions.astype("<f4"), FLOAT, "VEC3", ARRAY_BUFFER, True),
                "NORMAL": self.add(normals.astype("<f4"), FLOAT, "VEC3", ARRAY_BUFFER),
                "TEXCOORD_0": self.add(uvs.astype("<f4"), FLOAT, "VEC2", ARRAY_BUFFER),
            },
            "indices": indices,
            "material": material,
            "mode": 4,
        }


def camera_node():
    elevation = math.radians(CAMERA_ELEVATION_DEGREES)
    translation = [
        0.0,
        CAMERA_DISTANCE * math.sin(elevation),
        CAMERA_DISTANCE * math.cos(elevation),
    ]
    # Pitch down by the elevation (rotation about +x by -elevation) so -z looks at the origin.
    half = -0.5 * elevation
    rotation = [math.sin(half), 0.0, 0.0, math.cos(half)]
    return {"name": "camera", "camera": 0, "translation": translation, "rotation": rotation}


def build():
    buffer = BufferWriter()
    sphere = uv_sphere(SPHERE_RADIUS, LONGITUDE_SEGMENTS, LATITUDE_SEGMENTS)
    check_outward(sphere[0], sphere[3])
    ground = ground_quad(GROUND_HALF_SIZE, -SPHERE_RADIUS)
    sphere_primitive = buffer.mesh_primitive(*sphere, material=0)
    ground_primitive = buffer.mesh_primitive(*ground, material=1)
    gltf = {
        "asset": {"version": "2.0", "generator": "assets-scripts/make_material_preview.py"},
        "extensionsUsed": ["KHR_lights_punctual"],
        "scene": 0,
        "scenes": [
            {
                "name": "material-preview",
                "nodes": [0, 1, 2, 3],
                "extras": {
                    "environment": {"image": "studio.exr", "strength": 1.0, "rotation_degrees": 0.0}
                },
            }
        ],
        "nodes": [
            {"name": "sphere", "mesh": 0},
            {"name": "ground", "mesh": 1},
            camera_node(),
            {
                "name": "key-light",
                "translation": KEY_POSITION,
                "extensions": {"KHR_lights_punctual": {"light": 0}},
            },
        ],
        "meshes": [
            {"name": "sphere", "primitives": [sphere_primitive]},
            {"name": "ground", "primitives": [ground_primitive]},
        ],
        "materials": [
            {
                "name": "preview",
                "pbrMetallicRoughness": {
                    "baseColorFactor": PREVIEW_BASE_COLOR,
                    "metallicFactor": 1.0,
                    "roughnessFactor": PREVIEW_ROUGHNESS,
                },
                "extras": {"neural": "alum-bronze"},
            },
            {
                "name": "ground",
                "pbrMetallicRoughness": {
                    "baseColorFactor": [GROUND_ALBEDO, GROUND_ALBEDO, GROUND_ALBEDO, 1.0],
                    "metallicFactor": 0.0,
                    "roughnessFactor": 1.0,
                },
                "extras": {"bsdf": "diffuse"},
            },
        ],
        "cameras": [
            {
                "name": "camera",
                "type": "perspective",
                "perspective": {
                    "yfov": math.radians(CAMERA_YFOV_DEGREES),
                    "aspectRatio": 1.0,
                    "znear": 0.01,
                    "zfar": 1000.0,
                },
            }
        ],
        "extensions": {
            "KHR_lights_punctual": {
                "lights": [
                    {"name": "key", "type": "point", "color": KEY_COLOR, "intensity": KEY_INTENSITY}
                ]
            }
        },
        "buffers": [{"uri": "scene.bin", "byteLength": len(buffer.data)}],
        "bufferViews": buffer.views,
        "accessors": buffer.accessors,
    }
    return gltf, bytes(buffer.data)


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    default = os.path.join(here, "..", "scenes", "material-preview")
    out_dir = os.path.normpath(sys.argv[1] if len(sys.argv) > 1 else default)
    os.makedirs(out_dir, exist_ok=True)
    gltf, data = build()
    with open(os.path.join(out_dir, "scene.bin"), "wb") as f:
        f.write(data)
    with open(os.path.join(out_dir, "scene.gltf"), "w") as f:
        json.dump(gltf, f, indent=1)
        f.write("\n")
    fill = math.tan(math.asin(SPHERE_RADIUS / CAMERA_DISTANCE)) / math.tan(
        math.radians(CAMERA_YFOV_DEGREES / 2)
    )
    triangles = sum(
        gltf["accessors"][p["indices"]]["count"] // 3
        for m in gltf["meshes"]
        for p in m["primitives"]
    )
    print(
        f"wrote {out_dir}/scene.gltf + scene.bin ({len(data)} bytes): {triangles} triangles, "
        f"sphere fills {100 * fill:.0f}% of the frame height"
    )
    if not os.path.exists(os.path.join(out_dir, "studio.exr")):
        print("note: studio.exr is missing; run assets-scripts/make_studio_envmap.py")


if __name__ == "__main__":
    main()
