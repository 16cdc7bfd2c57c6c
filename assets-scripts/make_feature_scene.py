#!/usr/bin/env python3
"""Writes the feature-showcase scene: scenes/feature-showcase/scene.gltf + scene.bin + textures.

A small still life on a ground plane (y up, metres) that uses every glTF feature the renderer
reads, in one image, for a regression test and a side-by-side documentation image. Everything
below lies inside the camera's frame (the check asserts it, and that the fence's shadow does).

- "ground": a square of side 2 GROUND_HALF_SIZE at y = 0 with TEXCOORD_0 over
  [0, GROUND_UV_REPEATS] (u along +x, v along +z: v grows toward the camera, glTF's v-down
  convention seen from above) and no TANGENT attribute, so the renderer must build tangents
  itself (MikkTSpace). Material "ground-tiles": base colour ground_basecolor.jpg (a JPEG, sRGB:
  a 2 x 2 terracotta/sand checker with grout lines and a little noise; 25 cm tiles on the
  ground) through KHR_texture_transform (scale GROUND_TRANSFORM_SCALE, rotation
  GROUND_TRANSFORM_ROTATION radians, offset GROUND_TRANSFORM_OFFSET) with a REPEAT sampler;
  normalTexture ground_normal.png (tangent space, an egg-crate of bumps, no transform: its
  pattern is deliberately independent of the tiles) with scale 1; roughness 0.8, metallic 0.
- "brick-slab": a BRICK_SIZE box with explicit NORMAL and TANGENT (VEC4) attributes, four
  vertices per face, one texture repeat per BRICK_TEXTURE_METRES so bricks keep their size on
  every face. Tangents point along +u; w = +1 (bitangent = cross(N, T) * w = the image's up
  direction, i.e. towards -v) on every face but the -x face (the end turned towards the camera),
  whose u runs mirrored (right to left seen from outside) and whose tangents therefore have
  w = -1. Material "brick": base colour brick_basecolor.png (sRGB; red-brown bricks, grey mortar,
  two brass bricks per tile), normalTexture brick_normal.png (scale 1; bevelled bricks, recessed
  mortar, a fine grain; the brass bricks flat), metallicRoughnessTexture
  brick_metallic_roughness.png, a 16-bit RGB PNG of linear data in glTF's packing (green =
  roughness, blue = metallic, red unused = 1): bricks rough and dielectric with smooth per-brick
  variation, mortar roughness 0.95, the brass bricks metallic 1 and roughness about 0.28.
  metallicFactor = roughnessFactor = 1 so the texture alone decides.
- "fence": a FENCE_WIDTH x FENCE_HEIGHT vertical quad turned FENCE_YAW_DEGREES about y, its
  front towards the front left: square to the sun, seen obliquely by the camera. Material
  "fence-cutout": base colour fence_basecolor.png (RGBA, sRGB): a wooden frame and diagonal
  trellis with anti-aliased edges and alpha 0 in the holes; a top rail holding squares of alpha
  0.35 (below the cut-off: holes) and 0.65 (above: fully opaque, green) alternately. alphaMode
  MASK, alphaCutoff 0.5, doubleSided. The sun's shadow of the trellis falls on open ground
  behind and right of it.
- "glass-pane": a vertical quad, material "stained-glass": alphaMode BLEND, doubleSided,
  baseColorFactor [1, 1, 1, 0.5] times glass_basecolor.png (RGBA, sRGB: four coloured panes of
  alpha 0.6 in dark lead lines of alpha 1), i.e. coverage 0.3 in the panes and 0.5 on the lines.
  It stands over the ground tiles, in front of the sign's right end and the sphere's left edge,
  so each is seen both directly and through it.
- "sign": a SIGN_WIDTH x SIGN_HEIGHT quad facing the camera. Material "emissive-sign": a dark
  base colour, emissiveTexture sign_emissive.png (sRGB: the lettering "GLTF" in a 5 x 7 pixel
  font, a dashed line and a border; linear values at most SIGN_EMISSIVE_PEAK), emissiveFactor
  [1, 1, 1] and KHR_materials_emissive_strength SIGN_EMISSIVE_STRENGTH (peak radiance about 1).
  One-sided.
- "rock": ONE low-poly mesh (an icosahedron subdivided once, radii jittered, flattened,
  flat-shaded) instanced by ROCK_COUNT nodes "rock-00".. under the parent node "rock-garden"
  (its own translation and rotation about y). The instances have different translations,
  rotations (yaw plus a tilt) and non-uniform scales; "rock-ROCK_MIRRORED_INDEX" has a negative
  x scale (negative determinant: the renderer must flip its winding). The mesh has TEXCOORD_0 (a
  spherical mapping, u in [0, 1] plus the seam triangles' wrap) and TEXCOORD_1 (a top-down
  planar mapping, u = 0.9 + 0.2 x in [0.70, 1.11], v = 0.2 z in [-0.17, 0.16]: it never equals
  set 0); material "rock" reads its base colour rock_basecolor.png (64 x 64 speckles) through
  texCoord 1 with a sampler wrapS = CLAMP_TO_EDGE (u > 1 repeats the last column: streaks),
  wrapT = MIRRORED_REPEAT (v < 0 mirrors the first rows) and magFilter = minFilter = NEAREST
  (sharp texels).
- "neural-sphere": a UV sphere (SPHERE_SEGMENTS x SPHERE_RINGS, smooth normals, as in
  make_material_preview.py) of radius SPHERE_RADIUS resting on the ground. Material
  "neural-sphere" with extras {"neural": "alum-bronze"}: a latent code when the renderer is
  given a latent file (`render ... --material scenes/materials/latent.bin`), otherwise its
  copper-like core metallic-roughness parameters.
- "plastic-cylinder": a capped cylinder (CYLINDER_SEGMENTS sides, smooth side normals, flat
  caps). Material "glossy-plastic": a blue dielectric (metallic 0, roughness 0.15) with
  KHR_materials_ior (ior PLASTIC_IOR) and KHR_materials_specular (specularFactor
  PLASTIC_SPECULAR, specularColorFactor PLASTIC_SPECULAR_COLOR); both extensions are in
  extensionsUsed but not extensionsRequired, so a renderer without them uses the core
  parameters.
- Lights (KHR_lights_punctual, photometric units at LUMENS_PER_WATT): "sun", directional,
  SUN_IRRADIANCE W/m^2 written in lux, from SUN_ELEVATION_DEGREES above the horizon and
  travelling towards SUN_AZIMUTH_DEGREES (from the front left: raking light for the bumps,
  shadows to the back right); "lamp", a point light of LAMP_INTENSITY W/sr written in candela,
  front right.
- The environment, in the scene's extras: {"environment": {"color": ENVIRONMENT_COLOR}}, a dim
  uniform sky.
- "camera": perspective, yfov CAMERA_YFOV_DEGREES, aspect ratio 1, CAMERA_DISTANCE from
  CAMERA_TARGET and CAMERA_ELEVATION_DEGREES above it, looking at it.

Textures are 64 x 64 to 128 x 128 (the sign 128 x 64) and tile where a REPEAT sampler reads
them. Normal maps are tangent-space, 8-bit linear, glTF's convention: red = +u, green = the
image's up (towards -v, "OpenGL" style), blue = the normal. Everything is deterministic (fixed
seeds of numpy's frozen legacy RandomState, no timestamps), so re-running the script rewrites
identical bytes for the same numpy, Pillow and zlib. After writing, the script re-reads the
files and checks them (accessors, counts, bounds, alignment, unit normals and tangents, texture
handedness, images, extensions, node tree, instancing, framing, total size); `--check` only
checks an existing directory and compares it with what the script would write.

Usage: python3 assets-scripts/make_feature_scene.py [output-directory]
       python3 assets-scripts/make_feature_scene.py --check [directory]
Needs numpy and Pillow (`python3 -m pip install pillow`).
"""

import argparse
import io
import json
import math
import os
import struct
import sys
import zlib

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from gltf_buffer import ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER, FLOAT, BufferWriter  # noqa: E402
import make_material_preview  # noqa: E402

try:
    from PIL import Image
except ImportError:  # pragma: no cover - a clear message instead of a traceback
    sys.exit("make_feature_scene.py needs Pillow: python3 -m pip install pillow")

LUMENS_PER_WATT = 683.0  # glTF's photometric units: 683 cd = 1 W/sr, 683 lx = 1 W/m^2
CAMERA_TARGET = [-0.05, 0.05, -0.4]
CAMERA_DISTANCE = 3.9
CAMERA_ELEVATION_DEGREES = 32.0
CAMERA_YFOV_DEGREES = 40.0
CAMERA_ZNEAR = 0.01
CAMERA_ZFAR = 100.0
GROUND_HALF_SIZE = 4.0
GROUND_UV_REPEATS = 4.0  # TEXCOORD_0 spans [0, 4] over the ground (normal map: 2 m a tile)
GROUND_TRANSFORM_SCALE = [4.0, 4.0]  # base colour: 16 tiles over the ground, 0.5 m each
GROUND_TRANSFORM_ROTATION = 0.12  # radians
GROUND_TRANSFORM_OFFSET = [0.1, 0.05]
GROUND_ROUGHNESS = 0.8
BRICK_SIZE = [0.8, 0.3, 0.3]
BRICK_POSITION = [-1.0, 0.0, -1.0]  # centre of the bottom face
BRICK_YAW_DEGREES = 20.0
BRICK_TEXTURE_METRES = 0.4  # one texture repeat
FENCE_WIDTH = 0.9
FENCE_HEIGHT = 0.6
FENCE_POSITION = [-0.75, 0.0, 0.45]  # centre of the bottom edge
FENCE_YAW_DEGREES = -45.0  # its front (+z) turned towards the front left, facing the sun
GLASS_WIDTH = 0.42
GLASS_HEIGHT = 0.5
GLASS_POSITION = [0.45, 0.0, -0.7]
GLASS_YAW_DEGREES = 10.0
GLASS_ALPHA = 0.5
SIGN_WIDTH = 0.6
SIGN_HEIGHT = 0.3
SIGN_POSITION = [0.15, 0.0, -1.45]
SIGN_YAW_DEGREES = 0.0
SIGN_EMISSIVE_PEAK = 0.25  # linear value of the brightest texel
SIGN_EMISSIVE_STRENGTH = 4.0
SPHERE_RADIUS = 0.3
SPHERE_SEGMENTS = 64
SPHERE_RINGS = 32
SPHERE_POSITION = [0.95, SPHERE_RADIUS, -0.95]
NEURAL_MATERIAL = "neural-sphere"
NEURAL_LATENT = "alum-bronze"
COPPER_BASE_COLOR = [0.955, 0.638, 0.538, 1.0]  # copper's linear F0
COPPER_ROUGHNESS = 0.3
CYLINDER_RADIUS = 0.14
CYLINDER_HEIGHT = 0.5
CYLINDER_SEGMENTS = 48
CYLINDER_POSITION = [-0.4, 0.0, -1.3]
PLASTIC_BASE_COLOR = [0.04, 0.12, 0.5, 1.0]
PLASTIC_ROUGHNESS = 0.15
PLASTIC_IOR = 1.8
PLASTIC_SPECULAR = 0.7
PLASTIC_SPECULAR_COLOR = [1.0, 0.9, 0.8]
ROCK_COUNT = 18
ROCK_MIRRORED_INDEX = 5
ROCK_GARDEN_POSITION = [0.55, 0.0, 0.3]
ROCK_GARDEN_YAW_DEGREES = 20.0
ROCK_GARDEN_RADIUS = 0.45
ROCK_SCALE_RANGE = (0.06, 0.13)
SUN_ELEVATION_DEGREES = 30.0
SUN_AZIMUTH_DEGREES = -45.0  # horizontal travel: +x rotated 45 deg towards -z (to the back right)
SUN_IRRADIANCE = 3.0  # W/m^2
SUN_COLOR = [1.0, 0.96, 0.9]
LAMP_POSITION = [1.8, 2.0, 1.6]
LAMP_INTENSITY = 2.0  # W/sr
LAMP_COLOR = [1.0, 0.9, 0.8]
ENVIRONMENT_COLOR = [0.15, 0.17, 0.2]
MAX_DIRECTORY_BYTES = 400 * 1024
SEED = 20240611
DEFAULT_SCENE_DIR = os.path.normpath(
    os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scenes", "feature-showcase")
)

NEAREST, LINEAR, LINEAR_MIPMAP_LINEAR = 9728, 9729, 9987
REPEAT, CLAMP_TO_EDGE, MIRRORED_REPEAT = 10497, 33071, 33648

# ----------------------------------------------------------------------------------- helpers


def rng(part):
    """numpy's legacy RandomState (its streams are frozen across numpy versions), one per part."""
    return np.random.RandomState((SEED + 7919 * part) % (2**32))


def normalize(v):
    v = np.asarray(v, np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def quat_y(degrees):
    """glTF quaternion [x, y, z, w] of a rotation about +y."""
    half = 0.5 * math.radians(degrees)
    return [0.0, math.sin(half), 0.0, math.cos(half)]


def quat_axis_angle(axis, radians):
    x, y, z = normalize(axis)
    s = math.sin(0.5 * radians)
    return [float(x * s), float(y * s), float(z * s), math.cos(0.5 * radians)]


def quat_mul(a, b):
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return [
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    ]


def quat_to_matrix(q):
    x, y, z, w = q
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def matrix_to_quat(m):
    """Quaternion [x, y, z, w] of a proper rotation matrix (rows = output axes)."""
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    if trace > 0.0:
        s = 2.0 * math.sqrt(trace + 1.0)
        q = [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, 0.25 * s]
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = [0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s]
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = [(m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s]
    else:
        s = 2.0 * math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = [(m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s, (m[1, 0] - m[0, 1]) / s]
    q = normalize(q)
    return [float(c) for c in (q if q[3] >= 0.0 else -q)]


def look_rotation(forward, up=(0.0, 1.0, 0.0)):
    """Quaternion turning the node's -z onto `forward` with its +y as close to `up` as possible."""
    f = normalize(forward)
    right = normalize(np.cross(f, up))
    true_up = np.cross(right, f)
    return matrix_to_quat(np.stack([right, true_up, -f], axis=1))


def camera_position():
    elevation = math.radians(CAMERA_ELEVATION_DEGREES)
    t = CAMERA_TARGET
    return [
        t[0],
        t[1] + CAMERA_DISTANCE * math.sin(elevation),
        t[2] + CAMERA_DISTANCE * math.cos(elevation),
    ]


def sun_direction():
    """Unit direction the sunlight travels in (the sun node's -z)."""
    el, az = math.radians(SUN_ELEVATION_DEGREES), math.radians(SUN_AZIMUTH_DEGREES)
    return [math.cos(el) * math.cos(az), -math.sin(el), math.cos(el) * math.sin(az)]


def rounded(values, digits=6):
    """Floats for the JSON, rounded so the file reads cleanly (and stays deterministic)."""
    return [round(float(v), digits) + 0.0 for v in values]


# ------------------------------------------------------------------------------------ images


def srgb8(linear):
    """Linear [0, 1] values → 8-bit sRGB codes."""
    c = np.clip(np.asarray(linear, np.float64), 0.0, 1.0)
    encoded = np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1.0 / 2.4) - 0.055)
    return np.round(encoded * 255.0).astype(np.uint8)


def linear8(values):
    return np.round(np.clip(values, 0.0, 1.0) * 255.0).astype(np.uint8)


def png8_bytes(array):
    """8-bit PNG (RGB or RGBA from the last axis) encoded by Pillow, without metadata."""
    mode = {3: "RGB", 4: "RGBA"}[array.shape[2]]
    out = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(array, np.uint8), mode).save(
        out, format="PNG", compress_level=9
    )
    return out.getvalue()


def jpeg_bytes(array, quality=92):
    """Baseline JPEG, 4:4:4, by Pillow (no EXIF, no timestamps)."""
    out = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(array, np.uint8), "RGB").save(
        out, format="JPEG", quality=quality, subsampling=0, optimize=False, progressive=False
    )
    return out.getvalue()


def png16_bytes(rgb):
    """16-bit RGB PNG of a (height, width, 3) uint16 array, written directly (Pillow has no
    16-bit RGB mode). Each row takes the filter with the smallest sum of absolute differences
    (the PNG specification's heuristic)."""
    height, width, _ = rgb.shape
    bpp = 6
    rows = rgb.astype(">u2").reshape(height, width * bpp // 2).view(np.uint8).astype(np.int16)
    previous = np.zeros(width * bpp, np.int16)
    raw = bytearray()
    for row in rows:
        left = np.concatenate([np.zeros(bpp, np.int16), row[:-bpp]])
        up_left = np.concatenate([np.zeros(bpp, np.int16), previous[:-bpp]])
        p = left + previous - up_left
        pa, pb, pc = np.abs(p - left), np.abs(p - previous), np.abs(p - up_left)
        paeth = np.where((pa <= pb) & (pa <= pc), left, np.where(pb <= pc, previous, up_left))
        candidates = [
            row,
            row - left,
            row - previous,
            row - (left + previous) // 2,
            row - paeth,
        ]
        filtered = [(c % 256).astype(np.uint8) for c in candidates]
        costs = [int(np.abs(f.astype(np.int8).astype(np.int32)).sum()) for f in filtered]
        best = int(np.argmin(costs))
        raw.append(best)
        raw.extend(filtered[best].tobytes())
        previous = row

    def chunk(kind, data):
        return (
            struct.pack(">I", len(data))
            + kind
            + data
            + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)
        )

    header = struct.pack(">IIBBBBB", width, height, 16, 2, 0, 0, 0)
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", header)
        + chunk(b"IDAT", zlib.compress(bytes(raw), 9))
        + chunk(b"IEND", b"")
    )


def periodic_blur(field, passes=2):
    """Box blur with wrap-around (keeps textures tileable)."""
    for _ in range(passes):
        field = (
            field
            + np.roll(field, 1, 0)
            + np.roll(field, -1, 0)
            + np.roll(field, 1, 1)
            + np.roll(field, -1, 1)
        ) / 5.0
    return field


def normal_map(height, strength):
    """Tangent-space normal map (8-bit RGB, linear) of a tileable height field in texels:
    red = +u (right), green = image up (-v), blue = out of the surface."""
    d_right = (np.roll(height, -1, 1) - np.roll(height, 1, 1)) / 2.0
    d_down = (np.roll(height, -1, 0) - np.roll(height, 1, 0)) / 2.0
    n = normalize(np.stack([-strength * d_right, strength * d_down, np.ones_like(height)], -1))
    return linear8(0.5 * n + 0.5)


def texel_grid(width, height=None):
    """Texel-centre coordinates (x to the right, y down), in texels."""
    height = width if height is None else height
    y, x = np.mgrid[0:height, 0:width].astype(np.float64)
    return x + 0.5, y + 0.5


def ground_basecolor():
    """128 x 128: a 2 x 2 checker of terracotta and cream tiles with grout lines."""
    n, cell = 128, 64
    x, y = texel_grid(n)
    checker = ((x // cell + y // cell) % 2).astype(bool)
    color = np.where(checker[..., None], [0.3, 0.14, 0.08], [0.52, 0.46, 0.36])
    grain = periodic_blur(rng(1).uniform(-1.0, 1.0, (n, n)), 1)
    color = color * (1.0 + 0.12 * grain[..., None])
    grout = (np.minimum(x % cell, cell - x % cell) < 1.6) | (
        np.minimum(y % cell, cell - y % cell) < 1.6
    )
    color = np.where(grout[..., None], [0.18, 0.17, 0.16], color)
    return srgb8(color)


def ground_normal():
    """128 x 128 egg-crate bumps, 8 a side, tileable (integer frequency)."""
    n, f = 128, 8
    x, y = texel_grid(n)
    height = np.cos(2 * np.pi * f * x / n) * np.cos(2 * np.pi * f * y / n)
    amplitude = 0.45 / (2 * np.pi * f / n)  # steepest slope 0.45 (about 24 degrees)
    return normal_map(amplitude * height, 1.0)


def brick_layout(n=128):
    """Per texel of the n x n brick tile: brick id (-1 = mortar), distance to the mortar."""
    x, y = texel_grid(n)
    row_height, brick_width, mortar = n / 4, n / 2, 1.5
    row = (y // row_height).astype(int)
    xs = (x + (row % 2) * brick_width / 2) % n
    column = (xs // brick_width).astype(int)
    lx, ly = xs % brick_width, y % row_height
    edge = np.minimum(np.minimum(lx, brick_width - lx), np.minimum(ly, row_height - ly))
    brick = np.where(edge < mortar, -1, row * 2 + column)
    return brick, edge - mortar


BRASS_BRICKS = (2, 5)  # of the 8 bricks in a tile


def brick_textures():
    """(base colour RGB8 sRGB, normal map RGB8, metallic-roughness RGB16) of the brick tile."""
    n = 128
    brick, edge = brick_layout(n)
    r = rng(2)
    tints = r.uniform(0.75, 1.15, 8)
    rough = r.uniform(0.72, 0.9, 8)
    grain = periodic_blur(r.uniform(-1.0, 1.0, (n, n)), 1)
    blotch = periodic_blur(r.uniform(-1.0, 1.0, (n, n)), 12)
    blotch /= np.abs(blotch).max()
    brass = np.isin(brick, BRASS_BRICKS)
    mortar = brick < 0
    ids = np.maximum(brick, 0)

    color = np.array([0.36, 0.1, 0.05]) * tints[ids][..., None] * (1.0 + 0.15 * grain[..., None])
    color = np.where(
        brass[..., None], np.array([0.91, 0.78, 0.42]) * (1.0 + 0.03 * grain[..., None]), color
    )
    color = np.where(
        mortar[..., None], np.array([0.42, 0.41, 0.38]) * (1.0 + 0.1 * grain[..., None]), color
    )

    bevel = np.clip(edge / 3.5, 0.0, 1.0)
    bevel = bevel * bevel * (3.0 - 2.0 * bevel)
    height = np.where(mortar, 0.0, 2.0 * bevel + np.where(brass, 0.0, 0.35 * grain))
    normals = normal_map(height, 1.0)

    roughness = np.where(brass, 0.28 + 0.04 * blotch, rough[ids] + 0.06 * blotch)
    roughness = np.where(mortar, 0.95, roughness)
    metallic = np.where(brass, 1.0, 0.0)
    packed = np.stack([np.ones_like(roughness), roughness, metallic], -1)
    mr = np.round(np.clip(packed, 0.0, 1.0) * 65535.0).astype(np.uint16)
    return srgb8(color), normals, mr


def fence_basecolor():
    """128 x 128 RGBA: wooden frame, top rail of alpha-0.35/0.65 test squares, diagonal
    trellis; alpha 0 in the holes, anti-aliased (one-texel ramps) edges."""
    n = 128
    x, y = texel_grid(n)

    def coverage(distance, half_width):
        return np.clip(0.5 + half_width - distance, 0.0, 1.0)

    frame = np.maximum.reduce(
        [
            coverage(np.abs(x - 3.0), 3.0),
            coverage(np.abs(x - (n - 3.0)), 3.0),
            coverage(np.abs(y - 3.0), 3.0),
            coverage(np.abs(y - (n - 3.0)), 3.0),
            coverage(np.abs(y - 24.0), 2.5),
        ]
    )
    period = 32.0
    d1 = np.abs(((x + y) % period) - period / 2) - period / 2  # distance-ish to a diagonal
    d2 = np.abs(((x - y) % period) - period / 2) - period / 2
    trellis = np.maximum(coverage(-d1 / math.sqrt(2), 2.6), coverage(-d2 / math.sqrt(2), 2.6))
    trellis = np.where(y > 24.0, trellis, 0.0)
    alpha = np.maximum(frame, trellis)

    color = np.broadcast_to(np.array([0.33, 0.2, 0.1]), (n, n, 3)).copy()
    grain = periodic_blur(rng(3).uniform(-1.0, 1.0, (n, n)), 1)
    color *= 1.0 + 0.2 * grain[..., None]
    # Test squares on the top rail: 8 squares of 10 texels at x = 9 + 14 k, y in [9, 19).
    in_rail = (y > 9.0) & (y < 19.0)
    k = np.floor((x - 9.0) / 14.0)
    in_square = in_rail & (k >= 0) & (k < 8) & ((x - 9.0) - 14.0 * k < 10.0)
    square_alpha = np.where(k % 2 == 0, 0.65, 0.35)
    alpha = np.where(in_square, square_alpha, alpha)
    color = np.where(in_square[..., None], [0.08, 0.45, 0.12], color)
    rgba = np.concatenate([srgb8(color), linear8(alpha)[..., None]], -1)
    return rgba


def glass_basecolor():
    """128 x 128 RGBA: four coloured panes (alpha 0.6) in lead lines (alpha 1)."""
    n = 128
    x, y = texel_grid(n)
    panes = np.array([[0.2, 0.45, 0.9], [0.95, 0.6, 0.1], [0.2, 0.8, 0.3], [0.9, 0.3, 0.5]])
    index = (x // 64).astype(int) + 2 * (y // 64).astype(int)
    color = panes[index]
    centre_lines = (np.abs(x - 64.0) < 3.0) | (np.abs(y - 64.0) < 3.0)
    lead = centre_lines | (x < 4.0) | (x > n - 4.0) | (y < 4.0) | (y > n - 4.0)
    color = np.where(lead[..., None], [0.05, 0.05, 0.05], color)
    alpha = np.where(lead, 1.0, 0.6)
    return np.concatenate([srgb8(color), linear8(alpha)[..., None]], -1)


FONT_5X7 = {
    "G": [".###.", "#...#", "#....", "#.###", "#...#", "#...#", ".###."],
    "L": ["#....", "#....", "#....", "#....", "#....", "#....", "#####"],
    "T": ["#####", "..#..", "..#..", "..#..", "..#..", "..#..", "..#.."],
    "F": ["#####", "#....", "#....", "####.", "#....", "#....", "#...."],
}


def sign_emissive(text="GLTF"):
    """128 x 64 RGB (sRGB): lettering in a 5 x 7 font (4-texel pixels), a dashed line, border."""
    width, height, pixel = 128, 64, 4
    linear = np.zeros((height, width, 3))
    letter = np.array([1.0, 0.5, 0.12]) * SIGN_EMISSIVE_PEAK
    accent = np.array([0.12, 0.8, 1.0]) * SIGN_EMISSIVE_PEAK
    advance = 6 * pixel
    left = (width - (len(text) * advance - pixel)) // 2
    top = 8
    for i, ch in enumerate(text):
        for row, bits in enumerate(FONT_5X7[ch]):
            for col, bit in enumerate(bits):
                if bit == "#":
                    x0, y0 = left + i * advance + col * pixel, top + row * pixel
                    linear[y0 : y0 + pixel, x0 : x0 + pixel] = letter
    linear[44:48, 12:116] = 0.0
    for x0 in range(12, 116, 8):  # dashes
        linear[46:50, x0 : x0 + 5] = accent
    linear[:2, :] = linear[-2:, :] = accent
    linear[:, :2] = linear[:, -2:] = accent
    return srgb8(linear)


def rock_basecolor():
    """64 x 64 RGB (sRGB): speckled stone, one random palette colour per texel, so NEAREST
    filtering, clamping (streaks) and mirroring read clearly."""
    n = 64
    palette = np.array(
        [
            [0.12, 0.11, 0.1],
            [0.3, 0.28, 0.25],
            [0.5, 0.47, 0.42],
            [0.7, 0.64, 0.52],
            [0.45, 0.2, 0.1],
        ]
    )
    r = rng(4)
    choice = r.choice(len(palette), size=(n, n), p=[0.2, 0.3, 0.25, 0.15, 0.1])
    x, y = texel_grid(n)
    shade = 0.8 + 0.4 * (x + y) / (2 * n)  # a diagonal gradient shows the orientation
    return srgb8(palette[choice] * shade[..., None])


# ------------------------------------------------------------------------------------ meshes


def check_outward(positions, normals, triangles, what):
    """Counter-clockwise winding (glTF's front) agrees with the stored vertex normals."""
    p = positions.astype(np.float64)
    a, b, c = p[triangles[:, 0]], p[triangles[:, 1]], p[triangles[:, 2]]
    face = np.cross(b - a, c - a)
    assert np.all(np.linalg.norm(face, axis=1) > 0.0), f"{what}: degenerate triangle"
    vertex = normals[triangles].astype(np.float64).sum(axis=1)
    assert np.all(np.einsum("ij,ij->i", face, vertex) > 0.0), f"{what}: winding against normals"


def ground_quad():
    h = GROUND_HALF_SIZE
    positions = np.array([[-h, 0, h], [h, 0, h], [h, 0, -h], [-h, 0, -h]], np.float32)
    normals = np.tile(np.array([0.0, 1.0, 0.0], np.float32), (4, 1))
    uvs = GROUND_UV_REPEATS * (positions[:, [0, 2]] + h) / (2 * h)  # v grows with z
    triangles = np.array([[0, 1, 2], [0, 2, 3]], np.uint32)
    return {
        "POSITION": positions,
        "NORMAL": normals,
        "TEXCOORD_0": uvs.astype(np.float32),
    }, triangles


def upright_quad(width, height):
    """A quad in the local xy plane facing +z, bottom edge centred on the origin; uv (0, 0)
    at its top left seen from the front."""
    w = width / 2
    positions = np.array([[-w, 0, 0], [w, 0, 0], [w, height, 0], [-w, height, 0]], np.float32)
    normals = np.tile(np.array([0.0, 0.0, 1.0], np.float32), (4, 1))
    uvs = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], np.float32)
    triangles = np.array([[0, 1, 2], [0, 2, 3]], np.uint32)
    return {"POSITION": positions, "NORMAL": normals, "TEXCOORD_0": uvs}, triangles


def brick_box():
    """The brick slab (bottom face at y = 0): 4 vertices a face with NORMAL and TANGENT; the
    -x face's u runs mirrored, so its tangents have w = -1."""
    sx, sy, sz = (s / 2 for s in BRICK_SIZE)
    half = np.array([sx, sy, sz])
    centre = np.array([0.0, sy, 0.0])
    # (normal, right seen from outside, mirrored?) — up = cross(normal, right)
    faces = [
        ((1, 0, 0), (0, 0, -1), False),
        ((-1, 0, 0), (0, 0, 1), True),
        ((0, 1, 0), (1, 0, 0), False),
        ((0, -1, 0), (1, 0, 0), False),
        ((0, 0, 1), (1, 0, 0), False),
        ((0, 0, -1), (-1, 0, 0), False),
    ]
    positions, normals, tangents, uvs, triangles = [], [], [], [], []
    for normal, right, mirrored in faces:
        n, r = np.array(normal, float), np.array(right, float)
        up = np.cross(n, r)
        a, b = abs(r @ half), abs(up @ half)  # half extents along right and up
        base = len(positions)
        for cr, cu in ((-1, -1), (1, -1), (1, 1), (-1, 1)):  # CCW seen from outside
            positions.append(centre + n * abs(n @ half) + cr * a * r + cu * b * up)
            normals.append(n)
            along = (a + (cr * a if not mirrored else -cr * a)) / BRICK_TEXTURE_METRES
            uvs.append([along, (b - cu * b) / BRICK_TEXTURE_METRES])
            tangent = -r if mirrored else r
            tangents.append([*tangent, -1.0 if mirrored else 1.0])
        triangles += [[base, base + 1, base + 2], [base, base + 2, base + 3]]
    attributes = {
        "POSITION": np.array(positions, np.float32),
        "NORMAL": np.array(normals, np.float32),
        "TANGENT": np.array(tangents, np.float32),
        "TEXCOORD_0": np.array(uvs, np.float32),
    }
    return attributes, np.array(triangles, np.uint32)


def uv_sphere(radius, n_lon, n_lat):
    """A UV sphere centred on the origin (make_material_preview.py's)."""
    positions, normals, uvs, triangles = make_material_preview.uv_sphere(radius, n_lon, n_lat)
    return {"POSITION": positions, "NORMAL": normals, "TEXCOORD_0": uvs}, triangles


def cylinder(radius, height, segments):
    """Capped cylinder standing on y = 0: smooth sides (seam duplicated), flat caps."""
    positions, normals, uvs, triangles = [], [], [], []
    for i in range(segments + 1):
        phi = 2 * math.pi * i / segments
        direction = [math.sin(phi), 0.0, math.cos(phi)]
        for y, v in ((0.0, 1.0), (height, 0.0)):
            positions.append([radius * direction[0], y, radius * direction[2]])
            normals.append(direction)
            uvs.append([i / segments, v])
    for i in range(segments):
        b0, t0, b1, t1 = 2 * i, 2 * i + 1, 2 * i + 2, 2 * i + 3
        triangles += [[b0, b1, t1], [b0, t1, t0]]
    for y, ny in ((height, 1.0), (0.0, -1.0)):
        centre = len(positions)
        positions.append([0.0, y, 0.0])
        normals.append([0.0, ny, 0.0])
        uvs.append([0.5, 0.5])
        for i in range(segments):
            phi = 2 * math.pi * i / segments
            s, c = math.sin(phi), math.cos(phi)
            positions.append([radius * s, y, radius * c])
            normals.append([0.0, ny, 0.0])
            uvs.append([0.5 + 0.5 * s, 0.5 - 0.5 * c * ny])
        for i in range(segments):
            a, b = centre + 1 + i, centre + 1 + (i + 1) % segments
            triangles.append([centre, a, b] if ny > 0 else [centre, b, a])
    attributes = {
        "POSITION": np.array(positions, np.float32),
        "NORMAL": np.array(normals, np.float32),
        "TEXCOORD_0": np.array(uvs, np.float32),
    }
    return attributes, np.array(triangles, np.uint32)


def icosphere_once():
    """Unit icosahedron subdivided once: 42 vertices, 80 counter-clockwise-outward triangles."""
    t = (1.0 + math.sqrt(5.0)) / 2.0
    vertices = [
        [-1, t, 0],
        [1, t, 0],
        [-1, -t, 0],
        [1, -t, 0],
        [0, -1, t],
        [0, 1, t],
        [0, -1, -t],
        [0, 1, -t],
        [t, 0, -1],
        [t, 0, 1],
        [-t, 0, -1],
        [-t, 0, 1],
    ]
    faces = [
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ]
    vertices = [list(normalize(v)) for v in vertices]
    midpoint = {}

    def middle(a, b):
        key = (min(a, b), max(a, b))
        if key not in midpoint:
            vertices.append(list(normalize(np.add(vertices[a], vertices[b]))))
            midpoint[key] = len(vertices) - 1
        return midpoint[key]

    subdivided = []
    for a, b, c in faces:
        ab, bc, ca = middle(a, b), middle(b, c), middle(c, a)
        subdivided += [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
    return np.array(vertices), np.array(subdivided)


def rock():
    """The instanced rock: a jittered, flattened icosphere, flat-shaded (3 vertices a
    triangle); TEXCOORD_0 spherical (u in [0, 1], seam triangles wrapped past 1), TEXCOORD_1
    planar from above, u = 0.9 + 0.2 x, v = 0.2 z (partly beyond u = 1 and below v = 0)."""
    directions, faces = icosphere_once()
    radii = 1.0 + rng(5).uniform(-0.18, 0.18, len(directions))
    points = directions * radii[:, None] * np.array([1.0, 0.65, 0.85])
    corners = points[faces]  # (T, 3, 3)
    face_normals = normalize(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]))
    centroids = corners.mean(axis=1)
    assert np.all(np.einsum("ij,ij->i", face_normals, centroids) > 0.0), "rock winding"
    d = directions[faces]
    u = 0.5 + np.arctan2(d[..., 0], d[..., 2]) / (2 * np.pi)
    v = np.arccos(np.clip(d[..., 1], -1.0, 1.0)) / np.pi
    pole = np.hypot(d[..., 0], d[..., 2]) < 1e-9
    for t in range(len(faces)):  # no seam across a triangle; a pole takes its neighbours' u
        others = u[t][~pole[t]]
        if others.max() - others.min() > 0.5:
            u[t] = np.where(u[t] < 0.5, u[t] + 1.0, u[t])
            others = u[t][~pole[t]]
        u[t][pole[t]] = others.mean()
    uv1 = np.stack([0.9 + 0.2 * corners[..., 0], 0.2 * corners[..., 2]], -1)
    attributes = {
        "POSITION": corners.reshape(-1, 3).astype(np.float32),
        "NORMAL": np.repeat(face_normals, 3, axis=0).astype(np.float32),
        "TEXCOORD_0": np.stack([u, v], -1).reshape(-1, 2).astype(np.float32),
        "TEXCOORD_1": uv1.reshape(-1, 2).astype(np.float32),
    }
    return attributes, np.arange(3 * len(faces), dtype=np.uint32).reshape(-1, 3)


def rock_nodes(first_index):
    """ROCK_COUNT rock instances in the garden's local frame, non-overlapping, deterministic."""
    r = rng(6)
    placed, nodes = [], []
    while len(nodes) < ROCK_COUNT:
        radius = ROCK_GARDEN_RADIUS * math.sqrt(r.uniform())
        angle = r.uniform(0.0, 2 * math.pi)
        size = r.uniform(*ROCK_SCALE_RANGE)
        stretch = r.uniform(0.75, 1.3, 3)
        yaw, tilt = r.uniform(0.0, 360.0), r.uniform(0.0, 30.0)
        heading = r.uniform(0.0, 2 * math.pi)
        tilt_axis = [math.cos(heading), 0.0, math.sin(heading)]
        x, z = radius * math.cos(angle), radius * math.sin(angle)
        reach = size * stretch.max()
        if any(math.hypot(x - px, z - pz) < reach + pr + 0.02 for px, pz, pr in placed):
            continue
        placed.append((x, z, reach))
        i = len(nodes)
        scale = [size * s for s in stretch]
        if i == ROCK_MIRRORED_INDEX:
            scale[0] = -scale[0]
        rotation = normalize(quat_mul(quat_y(yaw), quat_axis_angle(tilt_axis, math.radians(tilt))))
        rotation = rotation if rotation[3] >= 0.0 else -rotation
        nodes.append(
            {
                "name": f"rock-{i:02d}",
                "mesh": first_index,
                "translation": rounded([x, 0.35 * scale[1], z]),
                "rotation": rounded(rotation, 8),
                "scale": rounded(scale),
            }
        )
    return nodes


# ------------------------------------------------------------------------------------- glTF


def checked_primitive(buffer, attributes, triangles, material, what):
    """`buffer.primitive` after checking unit normals and outward winding."""
    normals = attributes["NORMAL"]
    assert np.allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-6), f"{what}: normals"
    check_outward(attributes["POSITION"], normals, triangles, what)
    return buffer.primitive(attributes, triangles, material)


def texture_set():
    """(images, samplers, textures, encoded files): texture index by name in `textures`."""
    brick_color, brick_normal, brick_mr = brick_textures()
    files = {
        "ground_basecolor.jpg": jpeg_bytes(ground_basecolor()),
        "ground_normal.png": png8_bytes(ground_normal()),
        "brick_basecolor.png": png8_bytes(brick_color),
        "brick_normal.png": png8_bytes(brick_normal),
        "brick_metallic_roughness.png": png16_bytes(brick_mr),
        "fence_basecolor.png": png8_bytes(fence_basecolor()),
        "glass_basecolor.png": png8_bytes(glass_basecolor()),
        "sign_emissive.png": png8_bytes(sign_emissive()),
        "rock_basecolor.png": png8_bytes(rock_basecolor()),
    }
    samplers = [
        {
            "name": "repeat",
            "magFilter": LINEAR,
            "minFilter": LINEAR_MIPMAP_LINEAR,
            "wrapS": REPEAT,
            "wrapT": REPEAT,
        },
        {
            "name": "clamp",
            "magFilter": LINEAR,
            "minFilter": LINEAR,
            "wrapS": CLAMP_TO_EDGE,
            "wrapT": CLAMP_TO_EDGE,
        },
        {
            "name": "nearest-clamp-mirror",
            "magFilter": NEAREST,
            "minFilter": NEAREST,
            "wrapS": CLAMP_TO_EDGE,
            "wrapT": MIRRORED_REPEAT,
        },
    ]
    sampler_of = {
        "ground_basecolor.jpg": 0,
        "ground_normal.png": 0,
        "brick_basecolor.png": 0,
        "brick_normal.png": 0,
        "brick_metallic_roughness.png": 0,
        "fence_basecolor.png": 1,
        "glass_basecolor.png": 1,
        "sign_emissive.png": 1,
        "rock_basecolor.png": 2,
    }
    images, textures, index = [], [], {}
    for name in files:
        mime = "image/jpeg" if name.endswith(".jpg") else "image/png"
        images.append({"name": name.rsplit(".", 1)[0], "uri": name, "mimeType": mime})
        textures.append({"source": len(images) - 1, "sampler": sampler_of[name]})
        index[name] = len(textures) - 1
    return images, samplers, textures, index, files


def materials(tex):
    transform = {
        "KHR_texture_transform": {
            "offset": GROUND_TRANSFORM_OFFSET,
            "rotation": GROUND_TRANSFORM_ROTATION,
            "scale": GROUND_TRANSFORM_SCALE,
        }
    }
    return [
        {
            "name": "ground-tiles",
            "pbrMetallicRoughness": {
                "baseColorTexture": {"index": tex["ground_basecolor.jpg"], "extensions": transform},
                "metallicFactor": 0.0,
                "roughnessFactor": GROUND_ROUGHNESS,
            },
            "normalTexture": {"index": tex["ground_normal.png"], "scale": 1.0},
        },
        {
            "name": "brick",
            "pbrMetallicRoughness": {
                "baseColorTexture": {"index": tex["brick_basecolor.png"]},
                "metallicRoughnessTexture": {"index": tex["brick_metallic_roughness.png"]},
                "metallicFactor": 1.0,
                "roughnessFactor": 1.0,
            },
            "normalTexture": {"index": tex["brick_normal.png"], "scale": 1.0},
        },
        {
            "name": "fence-cutout",
            "pbrMetallicRoughness": {
                "baseColorTexture": {"index": tex["fence_basecolor.png"]},
                "metallicFactor": 0.0,
                "roughnessFactor": 0.7,
            },
            "alphaMode": "MASK",
            "alphaCutoff": 0.5,
            "doubleSided": True,
        },
        {
            "name": "stained-glass",
            "pbrMetallicRoughness": {
                "baseColorFactor": [1.0, 1.0, 1.0, GLASS_ALPHA],
                "baseColorTexture": {"index": tex["glass_basecolor.png"]},
                "metallicFactor": 0.0,
                "roughnessFactor": 0.1,
            },
            "alphaMode": "BLEND",
            "doubleSided": True,
        },
        {
            "name": "emissive-sign",
            "pbrMetallicRoughness": {
                "baseColorFactor": [0.02, 0.02, 0.02, 1.0],
                "metallicFactor": 0.0,
                "roughnessFactor": 0.5,
            },
            "emissiveTexture": {"index": tex["sign_emissive.png"]},
            "emissiveFactor": [1.0, 1.0, 1.0],
            "extensions": {
                "KHR_materials_emissive_strength": {"emissiveStrength": SIGN_EMISSIVE_STRENGTH}
            },
        },
        {
            "name": "rock",
            "pbrMetallicRoughness": {
                "baseColorTexture": {"index": tex["rock_basecolor.png"], "texCoord": 1},
                "metallicFactor": 0.0,
                "roughnessFactor": 0.9,
            },
        },
        {
            "name": NEURAL_MATERIAL,
            "pbrMetallicRoughness": {
                "baseColorFactor": COPPER_BASE_COLOR,
                "metallicFactor": 1.0,
                "roughnessFactor": COPPER_ROUGHNESS,
            },
            "extras": {"neural": NEURAL_LATENT},
        },
        {
            "name": "glossy-plastic",
            "pbrMetallicRoughness": {
                "baseColorFactor": PLASTIC_BASE_COLOR,
                "metallicFactor": 0.0,
                "roughnessFactor": PLASTIC_ROUGHNESS,
            },
            "extensions": {
                "KHR_materials_ior": {"ior": PLASTIC_IOR},
                "KHR_materials_specular": {
                    "specularFactor": PLASTIC_SPECULAR,
                    "specularColorFactor": PLASTIC_SPECULAR_COLOR,
                },
            },
        },
    ]


def placed(name, mesh, position, yaw_degrees):
    node = {"name": name, "mesh": mesh}
    if any(position):
        node["translation"] = rounded(position)
    if yaw_degrees:
        node["rotation"] = rounded(quat_y(yaw_degrees), 8)
    return node


def build():
    """(glTF dictionary, scene.bin bytes, {texture file name: bytes})."""
    buffer = BufferWriter()
    images, samplers, textures, tex, files = texture_set()
    parts = [  # (mesh name, geometry, material index)
        ("ground", ground_quad(), 0),
        ("brick-slab", brick_box(), 1),
        ("fence", upright_quad(FENCE_WIDTH, FENCE_HEIGHT), 2),
        ("glass-pane", upright_quad(GLASS_WIDTH, GLASS_HEIGHT), 3),
        ("sign", upright_quad(SIGN_WIDTH, SIGN_HEIGHT), 4),
        ("rock", rock(), 5),
        ("neural-sphere", uv_sphere(SPHERE_RADIUS, SPHERE_SEGMENTS, SPHERE_RINGS), 6),
        ("plastic-cylinder", cylinder(CYLINDER_RADIUS, CYLINDER_HEIGHT, CYLINDER_SEGMENTS), 7),
    ]
    meshes = [
        {"name": name, "primitives": [checked_primitive(buffer, *geometry, material, name)]}
        for name, geometry, material in parts
    ]
    mesh = {name: i for i, (name, _, _) in enumerate(parts)}
    nodes = [
        placed("ground", mesh["ground"], [0.0, 0.0, 0.0], 0.0),
        placed("brick-slab", mesh["brick-slab"], BRICK_POSITION, BRICK_YAW_DEGREES),
        placed("fence", mesh["fence"], FENCE_POSITION, FENCE_YAW_DEGREES),
        placed("glass-pane", mesh["glass-pane"], GLASS_POSITION, GLASS_YAW_DEGREES),
        placed("sign", mesh["sign"], SIGN_POSITION, SIGN_YAW_DEGREES),
        placed("neural-sphere", mesh["neural-sphere"], SPHERE_POSITION, 0.0),
        placed("plastic-cylinder", mesh["plastic-cylinder"], CYLINDER_POSITION, 0.0),
        {
            "name": "sun",
            "rotation": rounded(look_rotation(sun_direction()), 8),
            "extensions": {"KHR_lights_punctual": {"light": 0}},
        },
        {
            "name": "lamp",
            "translation": LAMP_POSITION,
            "extensions": {"KHR_lights_punctual": {"light": 1}},
        },
        {
            "name": "camera",
            "camera": 0,
            "translation": rounded(camera_position()),
            "rotation": rounded(look_rotation(np.subtract(CAMERA_TARGET, camera_position())), 8),
        },
    ]
    garden = len(nodes)
    rocks = rock_nodes(mesh["rock"])
    nodes.append(
        {
            "name": "rock-garden",
            "translation": ROCK_GARDEN_POSITION,
            "rotation": rounded(quat_y(ROCK_GARDEN_YAW_DEGREES), 8),
            "children": list(range(garden + 1, garden + 1 + len(rocks))),
        }
    )
    nodes += rocks
    gltf = {
        "asset": {"version": "2.0", "generator": "assets-scripts/make_feature_scene.py"},
        "extensionsUsed": [
            "KHR_lights_punctual",
            "KHR_materials_emissive_strength",
            "KHR_materials_ior",
            "KHR_materials_specular",
            "KHR_texture_transform",
        ],
        "scene": 0,
        "scenes": [
            {
                "name": "feature-showcase",
                "nodes": list(range(garden + 1)),
                "extras": {"environment": {"color": ENVIRONMENT_COLOR}},
            }
        ],
        "nodes": nodes,
        "meshes": meshes,
        "materials": materials(tex),
        "textures": textures,
        "samplers": samplers,
        "images": images,
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
                    {
                        "name": "sun",
                        "type": "directional",
                        "color": SUN_COLOR,
                        "intensity": SUN_IRRADIANCE * LUMENS_PER_WATT,
                    },
                    {
                        "name": "lamp",
                        "type": "point",
                        "color": LAMP_COLOR,
                        "intensity": LAMP_INTENSITY * LUMENS_PER_WATT,
                    },
                ]
            }
        },
        **buffer.gltf_fields("scene.bin"),
    }
    return gltf, bytes(buffer.data), files


def gltf_text(gltf):
    return json.dumps(gltf, indent=1, sort_keys=True) + "\n"


# ------------------------------------------------------------------------------------- check

COMPONENTS = {
    5120: ("i1", 1),
    5121: ("u1", 1),
    5122: ("<i2", 2),
    5123: ("<u2", 2),
    5125: ("<u4", 4),
    5126: ("<f4", 4),
}
WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
UPRIGHT_TEXTURED = ("ground", "fence", "glass-pane", "sign", "brick-slab")


def fail_unless(condition, message):
    if not condition:
        raise AssertionError(message)


def read_accessor(gltf, data, index):
    fail_unless(0 <= index < len(gltf["accessors"]), f"accessor {index} missing")
    a = gltf["accessors"][index]
    fail_unless(a["componentType"] in COMPONENTS, f"accessor {index}: componentType")
    fail_unless(a["type"] in WIDTH, f"accessor {index}: type")
    dtype, size = COMPONENTS[a["componentType"]]
    width = WIDTH[a["type"]]
    view = gltf["bufferViews"][a["bufferView"]]
    start = view.get("byteOffset", 0) + a.get("byteOffset", 0)
    fail_unless("byteStride" not in view, f"accessor {index}: unexpected byteStride")
    fail_unless(start % size == 0, f"accessor {index}: misaligned")
    fail_unless(
        a.get("byteOffset", 0) + a["count"] * width * size <= view["byteLength"],
        f"accessor {index} overruns its view",
    )
    values = np.frombuffer(data, dtype, a["count"] * width, start)
    return a, values.reshape(a["count"], width)


def node_matrix(node):
    if "matrix" in node:
        return np.array(node["matrix"], np.float64).reshape(4, 4).T
    m = np.eye(4)
    m[:3, :3] = quat_to_matrix(node.get("rotation", [0, 0, 0, 1])) * np.array(
        node.get("scale", [1, 1, 1])
    )
    m[:3, 3] = node.get("translation", [0, 0, 0])
    return m


def world_nodes(gltf):
    """[(node index, world matrix)] of the default scene; each node reached exactly once."""
    seen, out = set(), []
    stack = [(i, np.eye(4)) for i in reversed(gltf["scenes"][gltf.get("scene", 0)]["nodes"])]
    while stack:
        i, parent = stack.pop()
        fail_unless(
            0 <= i < len(gltf["nodes"]) and i not in seen, f"node {i} missing or reached twice"
        )
        seen.add(i)
        world = parent @ node_matrix(gltf["nodes"][i])
        out.append((i, world))
        stack += [(c, world) for c in reversed(gltf["nodes"][i].get("children", []))]
    fail_unless(len(seen) == len(gltf["nodes"]), "some nodes are not in the scene")
    return out


def extension_names(value):
    """Every key of every `extensions` object in the document."""
    names = set()
    if isinstance(value, dict):
        for key, item in value.items():
            if key == "extensions":
                names |= set(item)
            names |= extension_names(item)
    elif isinstance(value, list):
        for item in value:
            names |= extension_names(item)
    return names


def check_primitive(gltf, data, mesh, primitive):
    attributes = {name: read_accessor(gltf, data, i) for name, i in primitive["attributes"].items()}
    counts = {a["count"] for a, _ in attributes.values()}
    fail_unless(len(counts) == 1, f"mesh {mesh['name']}: attribute counts differ: {counts}")
    expected = {
        "POSITION": "VEC3",
        "NORMAL": "VEC3",
        "TANGENT": "VEC4",
        "TEXCOORD_0": "VEC2",
        "TEXCOORD_1": "VEC2",
    }
    for name, (a, _) in attributes.items():
        fail_unless(
            a["type"] == expected[name] and a["componentType"] == FLOAT,
            f"mesh {mesh['name']}: {name} type",
        )
    a, positions = attributes["POSITION"]
    fail_unless(
        a["min"] == [float(x) for x in positions.min(0)]
        and a["max"] == [float(x) for x in positions.max(0)],
        f"mesh {mesh['name']}: POSITION min/max",
    )
    ia, indices = read_accessor(gltf, data, primitive["indices"])
    fail_unless(
        ia["type"] == "SCALAR" and ia["componentType"] in (5121, 5123, 5125),
        f"mesh {mesh['name']}: index type",
    )
    fail_unless(
        ia["count"] % 3 == 0 and indices.max() < a["count"], f"mesh {mesh['name']}: indices"
    )
    fail_unless(primitive.get("mode", 4) == 4, "triangles only")
    tris = indices.reshape(-1, 3).astype(np.int64)
    _, normals = attributes["NORMAL"]
    fail_unless(
        np.allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-5),
        f"mesh {mesh['name']}: normals not unit",
    )
    check_outward(positions, normals, tris, mesh["name"])
    p = positions.astype(np.float64)
    e1, e2 = p[tris[:, 1]] - p[tris[:, 0]], p[tris[:, 2]] - p[tris[:, 0]]
    _, uv = attributes["TEXCOORD_0"]
    uv = uv.astype(np.float64)
    d1, d2 = uv[tris[:, 1]] - uv[tris[:, 0]], uv[tris[:, 2]] - uv[tris[:, 0]]
    det = d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]
    dp_du = (e1 * d2[:, 1:2] - e2 * d1[:, 1:2]) / det[:, None]
    dp_dv = (e2 * d1[:, 0:1] - e1 * d2[:, 0:1]) / det[:, None]
    face_n = np.cross(e1, e2)
    # +1: the image reads upright (u right, -v up) seen from the front; -1: mirrored.
    handedness = np.sign(np.einsum("ij,ij->i", np.cross(dp_du, -dp_dv), face_n))
    if "TANGENT" in attributes:
        _, tangents = attributes["TANGENT"]
        fail_unless(
            np.allclose(np.linalg.norm(tangents[:, :3], axis=1), 1.0, atol=1e-5),
            "tangents not unit",
        )
        fail_unless(np.all(np.abs(np.abs(tangents[:, 3]) - 1.0) == 0.0), "tangent w not +-1")
        fail_unless(
            np.allclose(np.einsum("ij,ij->i", tangents[:, :3], normals), 0.0, atol=1e-5),
            "tangents not normal-orthogonal",
        )
        t = tangents[tris[:, 0]].astype(np.float64)
        fail_unless(np.all(np.einsum("ij,ij->i", t[:, :3], dp_du) > 0.0), "tangent not along +u")
        fail_unless(
            np.all(t[:, 3] == handedness), "tangent w disagrees with the texture coordinates"
        )
        fail_unless(
            np.any(t[:, 3] < 0.0) and np.any(t[:, 3] > 0.0), "want both tangent handednesses"
        )
    elif mesh["name"] in UPRIGHT_TEXTURED:
        fail_unless(np.all(handedness > 0.0), f"mesh {mesh['name']}: texture mirrored")
    if "TEXCOORD_1" in attributes:
        _, uv1 = attributes["TEXCOORD_1"]
        fail_unless(not np.allclose(uv1, uv), "TEXCOORD_1 should differ from TEXCOORD_0")
    return positions, tris


def png_bit_depth(data):
    fail_unless(data[:8] == b"\x89PNG\r\n\x1a\n" and data[12:16] == b"IHDR", "not a PNG")
    return data[24], data[25]


def check_images(gltf, directory):
    for image in gltf["images"]:
        uri = image["uri"]
        fail_unless("/" not in uri and "\\" not in uri, f"{uri}: not a plain relative file name")
        with open(os.path.join(directory, uri), "rb") as f:
            data = f.read()
        with Image.open(io.BytesIO(data)) as decoded:
            decoded.load()
            kind = decoded.format
            mode, size = decoded.mode, decoded.size
        fail_unless(
            kind == {"image/png": "PNG", "image/jpeg": "JPEG"}[image["mimeType"]], f"{uri}: format"
        )
        fail_unless(64 <= min(size) and max(size) <= 128, f"{uri}: size {size}")
        if uri == "brick_metallic_roughness.png":
            fail_unless(png_bit_depth(data) == (16, 2), f"{uri}: not 16-bit RGB")
            raw = np.frombuffer(zlib.decompress(data[data.index(b"IDAT") + 4 : -16]), np.uint8)
            fail_unless(raw.size == size[1] * (1 + 6 * size[0]), f"{uri}: IDAT size")
        if uri in ("fence_basecolor.png", "glass_basecolor.png"):
            fail_unless(mode == "RGBA", f"{uri}: no alpha channel")
    with Image.open(os.path.join(directory, "fence_basecolor.png")) as fence:
        alpha = np.asarray(fence)[..., 3]
    fail_unless((alpha == 0).mean() > 0.2 and (alpha == 255).mean() > 0.2, "fence: holes and slats")
    fail_unless(np.any(alpha == 89) and np.any(alpha == 166), "fence: 0.35 / 0.65 test squares")


def project(camera_node_world, yfov, points):
    """Normalised device coordinates (x, y in [-1, 1] inside an aspect-1 frame), depth."""
    inverse = np.linalg.inv(camera_node_world)
    local = (inverse[:3, :3] @ points.T).T + inverse[:3, 3]
    depth = -local[:, 2]
    f = 1.0 / math.tan(yfov / 2)
    return np.stack([f * local[:, 0] / depth, f * local[:, 1] / depth], -1), depth


def check_scene(directory):
    """Re-reads the written files and checks them; returns a summary line."""
    with open(os.path.join(directory, "scene.gltf")) as f:
        gltf = json.load(f)
    fail_unless(gltf["asset"]["version"] == "2.0", "asset.version")
    fail_unless(len(gltf["buffers"]) == 1, "one buffer")
    with open(os.path.join(directory, gltf["buffers"][0]["uri"]), "rb") as f:
        data = f.read()
    fail_unless(
        len(data) == gltf["buffers"][0]["byteLength"], "buffer byteLength != scene.bin size"
    )
    for i, view in enumerate(gltf["bufferViews"]):
        fail_unless(
            view["buffer"] == 0 and view["byteOffset"] % 4 == 0, f"bufferView {i}: alignment"
        )
        fail_unless(
            view["byteOffset"] + view["byteLength"] <= len(data),
            f"bufferView {i} overruns the buffer",
        )
        fail_unless(
            view.get("target") in (ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER), f"bufferView {i}: target"
        )
    used = set(gltf.get("extensionsUsed", []))
    fail_unless(
        extension_names(gltf) == used,
        f"extensionsUsed {sorted(used)} != used {sorted(extension_names(gltf))}",
    )
    fail_unless("extensionsRequired" not in gltf, "nothing should be required")
    for material in gltf["materials"]:
        for key in ("baseColorTexture", "metallicRoughnessTexture"):
            info = material["pbrMetallicRoughness"].get(key)
            fail_unless(
                info is None or info["index"] < len(gltf["textures"]), f"{material['name']}: {key}"
            )
        for key in ("normalTexture", "emissiveTexture", "occlusionTexture"):
            fail_unless(
                material.get(key, {"index": 0})["index"] < len(gltf["textures"]),
                f"{material['name']}: {key}",
            )
    for texture in gltf["textures"]:
        fail_unless(
            texture["source"] < len(gltf["images"]) and texture["sampler"] < len(gltf["samplers"]),
            "texture refs",
        )
    check_images(gltf, directory)

    geometry = [check_primitive(gltf, data, m, m["primitives"][0]) for m in gltf["meshes"]]
    fail_unless(
        all(
            len(m["primitives"]) == 1 and m["primitives"][0]["material"] < len(gltf["materials"])
            for m in gltf["meshes"]
        ),
        "primitives",
    )
    worlds = world_nodes(gltf)
    names = {gltf["nodes"][i]["name"]: (i, w) for i, w in worlds}
    camera_index, camera_world = names["camera"]
    camera = gltf["cameras"][gltf["nodes"][camera_index]["camera"]]
    fail_unless(
        camera["name"] == "camera" and camera["perspective"]["aspectRatio"] == 1.0, "camera"
    )
    yfov = camera["perspective"]["yfov"]
    rock_mesh = [m["name"] for m in gltf["meshes"]].index("rock")
    rock_worlds = [w for i, w in worlds if gltf["nodes"][i].get("mesh") == rock_mesh]
    fail_unless(len(rock_worlds) >= 16, "at least 16 rock instances")
    fail_unless(any(np.linalg.det(w[:3, :3]) < 0 for w in rock_worlds), "a mirrored rock")
    fail_unless(
        any("children" in gltf["nodes"][i] and "rotation" in gltf["nodes"][i] for i, _ in worlds),
        "a rotated parent",
    )
    worst = 0.0
    for i, world in worlds:
        node = gltf["nodes"][i]
        if "mesh" not in node or node["name"] == "ground":
            continue
        positions, _ = geometry[node["mesh"]]
        points = (world[:3, :3] @ positions.astype(np.float64).T).T + world[:3, 3]
        ndc, depth = project(camera_world, yfov, points)
        fail_unless(np.all(depth > 0.0), f"{node['name']} behind the camera")
        worst = max(worst, float(np.abs(ndc).max()))
        fail_unless(
            np.abs(ndc).max() < 0.97, f"{node['name']} leaves the frame ({np.abs(ndc).max():.3f})"
        )
    # The fence's shadow (its corners projected along the sunlight onto y = 0) is in frame.
    sun_world = names["sun"][1]
    sun = -sun_world[:3, 2] / np.linalg.norm(sun_world[:3, 2])
    fence_world = names["fence"][1]
    corners = (
        fence_world[:3, :3]
        @ geometry[[m["name"] for m in gltf["meshes"]].index("fence")][0].astype(np.float64).T
    ).T + fence_world[:3, 3]
    fence_normal = fence_world[:3, 2] / np.linalg.norm(fence_world[:3, 2])
    to_camera = camera_world[:3, 3] - corners.mean(axis=0)
    fail_unless(
        sun[1] < 0.0 and fence_normal @ -sun > 0.5, "the sun should light the fence's front"
    )
    fail_unless(fence_normal @ to_camera > 0.0, "the camera should see the fence's front")
    shadow = corners - sun[None, :] * (corners[:, 1:2] / sun[1])
    ndc, _ = project(camera_world, yfov, shadow)
    fail_unless(np.abs(ndc).max() < 0.97, "the fence's shadow leaves the frame")
    # The brick faces with mirrored texture coordinates (tangent w = -1) face the camera.
    brick_mesh = gltf["meshes"][[m["name"] for m in gltf["meshes"]].index("brick-slab")]
    attributes = brick_mesh["primitives"][0]["attributes"]
    _, tangents = read_accessor(gltf, data, attributes["TANGENT"])
    _, normals = read_accessor(gltf, data, attributes["NORMAL"])
    brick_positions = geometry[[m["name"] for m in gltf["meshes"]].index("brick-slab")][0]
    brick_world = names["brick-slab"][1]
    mirrored = tangents[:, 3] < 0.0
    points = (brick_world[:3, :3] @ brick_positions[mirrored].astype(np.float64).T).T + brick_world[
        :3, 3
    ]
    facing = (brick_world[:3, :3] @ normals[mirrored].astype(np.float64).T).T
    fail_unless(
        np.all(np.einsum("ij,ij->i", facing, camera_world[:3, 3] - points) > 0.0),
        "mirrored brick face hidden",
    )
    total = sum(os.path.getsize(os.path.join(directory, n)) for n in os.listdir(directory))
    fail_unless(total <= MAX_DIRECTORY_BYTES, f"directory is {total} bytes")
    return (
        f"checked: {len(gltf['accessors'])} accessors, {len(gltf['meshes'])} meshes, "
        f"{len(rock_worlds)} rock instances, {len(gltf['images'])} images; objects within "
        f"{100 * worst:.0f}% of the half-frame; {total} bytes in all"
    )


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("output", nargs="?", default=DEFAULT_SCENE_DIR, help="output directory")
    parser.add_argument("--check", action="store_true", help="only check that the files there are what the script writes")
    args = parser.parse_args()
    check_only = args.check
    out_dir = os.path.normpath(args.output)
    gltf, data, files = build()
    outputs = {"scene.gltf": gltf_text(gltf).encode(), "scene.bin": data, **files}
    if check_only:
        for name, content in outputs.items():
            with open(os.path.join(out_dir, name), "rb") as f:
                fail_unless(f.read() == content, f"{name} differs from what the script writes")
        print(f"{out_dir}: the files are what the script writes")
    else:
        os.makedirs(out_dir, exist_ok=True)
        for name, content in outputs.items():
            with open(os.path.join(out_dir, name), "wb") as f:
                f.write(content)
        sizes = ", ".join(f"{n} {len(c)}" for n, c in outputs.items())
        print(f"wrote {out_dir}: {sizes} bytes")
    print(check_scene(out_dir))


if __name__ == "__main__":
    main()
