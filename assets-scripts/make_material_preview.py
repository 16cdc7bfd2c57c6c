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
  of radiant intensity KEY_INTENSITY W/sr, written in the specification's photometric unit
  (candela: KEY_INTENSITY x LUMENS_PER_WATT, the 683 lm/W glTF and Blender's exporter use).
- The environment, named in the scene's extras: studio.exr next to the scene file (made by
  make_studio_envmap.py).

The same scene for Mitsuba 3: `mitsuba_scene(sphere_bsdf)` returns a `mi.load_dict` dictionary
built from the same constants and the same mesh arrays, with the sphere's BSDF as the parameter
(its docstring lists how each part maps); assets-scripts/compare_preview_mitsuba.py renders both.

Usage: python3 assets-scripts/make_material_preview.py [output-directory]
Needs numpy only (mitsuba_scene also needs Mitsuba 3, imported only when it is called).
"""

import argparse
import json
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from gltf_buffer import BufferWriter  # noqa: E402

SPHERE_RADIUS = 0.37
LONGITUDE_SEGMENTS = 128
LATITUDE_SEGMENTS = 64
CAMERA_DISTANCE = 2.0
CAMERA_YFOV_DEGREES = 30.0
CAMERA_ELEVATION_DEGREES = 10.0
CAMERA_ZNEAR = 0.01
CAMERA_ZFAR = 1000.0
GROUND_HALF_SIZE = 50.0
GROUND_ALBEDO = 0.5
KEY_POSITION = [-1.5, 2.0, 1.5]
KEY_COLOR = [1.0, 0.92, 0.82]
KEY_INTENSITY = 10.0  # W/sr
LUMENS_PER_WATT = 683.0  # glTF's photometric units: 683 cd = 1 W/sr
PREVIEW_MATERIAL = "preview"
PREVIEW_BASE_COLOR = [0.955, 0.638, 0.538, 1.0]  # copper's linear F0
PREVIEW_ROUGHNESS = 0.3
ENVIRONMENT_IMAGE = "studio.exr"
ENVIRONMENT_STRENGTH = 1.0
ENVIRONMENT_ROTATION_DEGREES = 0.0
DEFAULT_SCENE_DIR = os.path.normpath(
    os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scenes", "material-preview")
)



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


def camera_position():
    """World position of the camera: CAMERA_DISTANCE from the origin, raised by the elevation."""
    elevation = math.radians(CAMERA_ELEVATION_DEGREES)
    return [
        0.0,
        CAMERA_DISTANCE * math.sin(elevation),
        CAMERA_DISTANCE * math.cos(elevation),
    ]


def camera_node():
    elevation = math.radians(CAMERA_ELEVATION_DEGREES)
    translation = camera_position()
    # Pitch down by the elevation (rotation about +x by -elevation) so -z looks at the origin.
    half = -0.5 * elevation
    rotation = [math.sin(half), 0.0, 0.0, math.cos(half)]
    return {"name": "camera", "camera": 0, "translation": translation, "rotation": rotation}


def build():
    buffer = BufferWriter()
    sphere = uv_sphere(SPHERE_RADIUS, LONGITUDE_SEGMENTS, LATITUDE_SEGMENTS)
    check_outward(sphere[0], sphere[3])
    ground = ground_quad(GROUND_HALF_SIZE, -SPHERE_RADIUS)
    def mesh_primitive(positions, normals, uvs, triangles, material):
        return buffer.primitive({"POSITION": positions, "NORMAL": normals, "TEXCOORD_0": uvs}, triangles, material)

    sphere_primitive = mesh_primitive(*sphere, material=0)
    ground_primitive = mesh_primitive(*ground, material=1)
    gltf = {
        "asset": {"version": "2.0", "generator": "assets-scripts/make_material_preview.py"},
        "extensionsUsed": ["KHR_lights_punctual"],
        "scene": 0,
        "scenes": [
            {
                "name": "material-preview",
                "nodes": [0, 1, 2, 3],
                "extras": {
                    "environment": {
                        "image": ENVIRONMENT_IMAGE,
                        "strength": ENVIRONMENT_STRENGTH,
                        "rotation_degrees": ENVIRONMENT_ROTATION_DEGREES,
                    }
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
                "name": PREVIEW_MATERIAL,
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
                    "znear": CAMERA_ZNEAR,
                    "zfar": CAMERA_ZFAR,
                },
            }
        ],
        "extensions": {
            "KHR_lights_punctual": {
                "lights": [
                    {"name": "key", "type": "point", "color": KEY_COLOR, "intensity": KEY_INTENSITY * LUMENS_PER_WATT}
                ]
            }
        },
        **buffer.gltf_fields("scene.bin"),
    }
    return gltf, bytes(buffer.data)


# ------------------------------------------------------------------------------------ Mitsuba 3


def _mitsuba():
    """The imported mitsuba module, which must already have a variant set."""
    import mitsuba as mi

    if not mi.variant():
        raise RuntimeError("mitsuba_scene: call mitsuba.set_variant(...) first")
    return mi


def mitsuba_mesh(name, positions, normals, uvs, triangles, bsdf):
    """A Mitsuba mesh built in memory from the glTF's arrays, with smooth vertex normals.

    `bsdf` is a load_dict dictionary or an instantiated mi.BSDF. Texture coordinates are passed
    unchanged (v = 0 at the top, as glTF; Mitsuba's own OBJ/PLY loaders also store v = 0 at the
    top after flipping those formats' v).
    """
    mi = _mitsuba()
    props = mi.Properties()
    props["bsdf"] = mi.load_dict(bsdf) if isinstance(bsdf, dict) else bsdf
    mesh = mi.Mesh(
        name,
        int(positions.shape[0]),
        int(triangles.shape[0]),
        props=props,
        has_vertex_normals=True,
        has_vertex_texcoords=True,
    )
    params = mi.traverse(mesh)
    for key, array in (
        ("vertex_positions", positions),
        ("vertex_normals", normals),
        ("vertex_texcoords", uvs),
        ("faces", triangles),
    ):
        params[key] = type(params[key])(np.ascontiguousarray(array).reshape(-1))
    params.update()
    return mesh


def mitsuba_environment_bitmap(path, supersample=4):
    """The environment image as a Mitsuba Bitmap whose bilinear `envmap` look-up approximates
    our renderer's nearest-texel look-up.

    Our renderer (renderer/src/lights/environment.rs) gives texel (i, j) of a W x H map the cell
    u in [i/W, (i+1)/W), v in [j/H, (j+1)/H), constant inside. Mitsuba's envmap interpolates
    bilinearly between texel centres at u = (i + 0.5)/W and v = j/(H - 1) (its rows reach both
    poles), which blurs the map and stretches it by half a row at the poles: 0.23 % more mean
    radiance over the sphere for studio.exr. With `supersample` k > 1 the map is resampled
    (nearest, from our cells) to kW x kH at exactly Mitsuba's texel centres, so the blur and the
    stretch shrink to 1/k of a texel (k = 4: 0.09 %, k = 8: within the 0.05 % noise of the
    check). k = 1 passes the file's texels unchanged.
    """
    mi = _mitsuba()
    bitmap = mi.Bitmap(path)
    if supersample <= 1:
        return bitmap
    texels = np.array(
        bitmap.convert(mi.Bitmap.PixelFormat.RGB, mi.Struct.Type.Float32, False), np.float32
    )
    height, width = texels.shape[:2]
    k = int(supersample)
    cols = np.minimum(((np.arange(k * width) + 0.5) / (k * width) * width).astype(int), width - 1)
    rows = np.minimum((np.arange(k * height) / (k * height - 1) * height).astype(int), height - 1)
    return mi.Bitmap(np.ascontiguousarray(texels[rows][:, cols]))


def mitsuba_scene(
    sphere_bsdf,
    width=128,
    height=128,
    max_depth=8,
    scene_dir=DEFAULT_SCENE_DIR,
    spp=256,
    env_supersample=4,
):
    """The material-preview scene as a `mi.load_dict` dictionary, from this script's constants.

    Call `mitsuba.set_variant(...)` first (and register any plugin BSDF the sphere uses): the
    two meshes are built in memory (`mi.Mesh`, same arrays as scene.bin), so the dictionary holds
    instantiated objects. `sphere_bsdf` is a BSDF dictionary (e.g. {"type": "diffuse"}, or a
    plugin's {"type": "neural_brdf", ...}) or an mi.BSDF.

    Correspondence with scene.gltf as our renderer reads it:
    - sphere / ground: the uv_sphere() and ground_quad() arrays (positions, vertex normals, uvs,
      triangles); the ground is Mitsuba's one-sided `diffuse` with reflectance GROUND_ALBEDO
      (ours: Lambert, extras.bsdf = "diffuse").
    - camera: `perspective`, look_at from camera_position() to the origin with up +y (the
      glTF node's -z looks at the origin; image right = +x in both), fov CAMERA_YFOV_DEGREES on
      fov_axis "y" (ours keeps yfov for any output aspect), film width x height, `box`
      reconstruction filter (ours averages uniformly jittered samples within each pixel),
      independent sampler with `spp` samples.
    - key light: `point` at KEY_POSITION with intensity KEY_INTENSITY x KEY_COLOR in W/sr (the
      glTF holds it in candela, which ours divides by 683 lm/W).
    - environment: `envmap` of ENVIRONMENT_IMAGE in scene_dir, scale ENVIRONMENT_STRENGTH,
      to_world = rotation about +y by ENVIRONMENT_ROTATION_DEGREES + 180. Ours maps direction d
      to u = 0.5 + atan2(d.x, -d.z)/2pi, v = acos(d.y)/pi (image centre toward -z) and turns the
      map by +r about +y; Mitsuba's envmap uses u = atan2(d.x, -d.z)/2pi, the same formula
      without the 0.5, i.e. half a turn apart. Texel filtering differs (see
      mitsuba_environment_bitmap; `env_supersample` = 1 uses the file as is).
    - integrator: `path` with max_depth (our --max-depth has Mitsuba's meaning); both use
      next-event estimation with MIS and Russian roulette (unbiased, so means agree).
    """
    mi = _mitsuba()
    positions, normals, uvs, triangles = uv_sphere(
        SPHERE_RADIUS, LONGITUDE_SEGMENTS, LATITUDE_SEGMENTS
    )
    ground = ground_quad(GROUND_HALF_SIZE, -SPHERE_RADIUS)
    ground_bsdf = {
        "type": "diffuse",
        "reflectance": {"type": "rgb", "value": [GROUND_ALBEDO] * 3},
    }
    to_world = mi.ScalarTransform4f()
    return {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": int(max_depth)},
        "sensor": {
            "type": "perspective",
            "fov_axis": "y",
            "fov": CAMERA_YFOV_DEGREES,
            "near_clip": CAMERA_ZNEAR,
            "far_clip": CAMERA_ZFAR,
            "to_world": to_world.look_at(
                origin=camera_position(), target=[0.0, 0.0, 0.0], up=[0.0, 1.0, 0.0]
            ),
            "sampler": {"type": "independent", "sample_count": int(spp)},
            "film": {
                "type": "hdrfilm",
                "width": int(width),
                "height": int(height),
                "pixel_format": "rgb",
                "rfilter": {"type": "box"},
            },
        },
        "sphere": mitsuba_mesh("sphere", positions, normals, uvs, triangles, sphere_bsdf),
        "ground": mitsuba_mesh("ground", *ground, ground_bsdf),
        "key-light": {
            "type": "point",
            "position": KEY_POSITION,
            "intensity": {"type": "rgb", "value": [KEY_INTENSITY * c for c in KEY_COLOR]},
        },
        "environment": {
            "type": "envmap",
            "bitmap": mitsuba_environment_bitmap(
                os.path.join(scene_dir, ENVIRONMENT_IMAGE), env_supersample
            ),
            "scale": ENVIRONMENT_STRENGTH,
            "to_world": to_world.rotate([0.0, 1.0, 0.0], ENVIRONMENT_ROTATION_DEGREES + 180.0),
        },
    }


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
    if not os.path.exists(os.path.join(out_dir, ENVIRONMENT_IMAGE)):
        print("note: studio.exr is missing; run assets-scripts/make_studio_envmap.py")


if __name__ == "__main__":
    main()
