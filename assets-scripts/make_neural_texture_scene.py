#!/usr/bin/env python3
"""Writes the spatially varying neural-material scene: scenes/neural-texture/.

Three spheres of the material preview's size on its grey ground, under its studio
environment (../material-preview/studio.exr) and key light, each driving codes of the
shipped latent file with a texture (the glTF material extras forms of docs/neural-textures.md):

- "worn" (left): worn paint, the exact mixture of two codes, dark-red-paint where the paint
  is intact and aluminium where it chipped off; mask.png's red channel weighs the paint, its
  green channel the metal (linear).
- "ramp" (middle): a latent blend from gold-metallic-paint (t = 0) to
  silver-metallic-paint (t = 1), t read
  from ramp.png's red channel (linear), rising across the sphere's visible face from left
  to right (u = 0.25 ... 0.75), clamped at the edges by the sampler.
- "painted" (right): one code, specular-white-phenolic, with a painted colour (tint.png,
  sRGB: coloured stripes) multiplying its f_r.

Without a latent file (`render scene.gltf` alone) the spheres render with their own glTF
parameters. Render:

    render scenes/neural-texture/scene.gltf --material scenes/materials/latent.bin -o out.png

Usage: python3 assets-scripts/make_neural_texture_scene.py [output-directory]
Needs numpy and Pillow. The textures are made from a fixed seed, byte for byte the same.
"""

import argparse
import json
import math
import os
import sys

import numpy as np
from PIL import Image

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from gltf_buffer import BufferWriter  # noqa: E402
import make_material_preview as preview  # noqa: E402

SEED = 7
SPACING = 0.85  # between sphere centres, along x
CAMERA_DISTANCE = 3.4
CAMERA_YFOV_DEGREES = 24.0
ASPECT_RATIO = 2.0
MASK_SIZE = (256, 128)
CHIPPED_FRACTION = 0.3  # of the mask's texels
RAMP_WIDTH = 256
TINT_SIZE = (256, 128)
# (name, glTF fallback base colour, metallic, roughness, neural extras)
SPHERES = [
    (
        "worn",
        [0.45, 0.05, 0.04, 1.0], 0.0, 0.4,
        {"mix": ["dark-red-paint", "aluminium"], "weights": {"index": 0}},
    ),
    (
        "ramp",
        [0.8, 0.5, 0.1, 1.0], 0.5, 0.3,
        {"blend": ["gold-metallic-paint", "silver-metallic-paint"], "t": {"index": 1}, "channel": 0},
    ),
    (
        "painted",
        [0.9, 0.9, 0.9, 1.0], 0.0, 0.2,
        {"code": "specular-white-phenolic", "tint": {"index": 2}},
    ),
]
DEFAULT_SCENE_DIR = os.path.normpath(
    os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scenes", "neural-texture")
)


def smooth_noise(rng, shape, octaves=3):
    """Value noise in [0, 1] (sum of bilinearly upsampled random grids), tiling in x."""
    h, w = shape
    total = np.zeros(shape)
    for octave in range(octaves):
        cells = 16 * 2**octave
        grid = rng.random((cells // 2 + 1, cells + 1))
        grid[:, -1] = grid[:, 0]  # tiles around the sphere's seam
        y = np.linspace(0, grid.shape[0] - 1, h)
        x = np.linspace(0, grid.shape[1] - 1, w)
        y0, x0 = np.floor(y).astype(int).clip(0, grid.shape[0] - 2), np.floor(x).astype(int).clip(0, grid.shape[1] - 2)
        fy, fx = (y - y0)[:, None], (x - x0)[None, :]
        g = grid
        value = (
            (1 - fy) * (1 - fx) * g[y0][:, x0]
            + (1 - fy) * fx * g[y0][:, x0 + 1]
            + fy * (1 - fx) * g[y0 + 1][:, x0]
            + fy * fx * g[y0 + 1][:, x0 + 1]
        )
        total += value / 2**octave
    total -= total.min()
    return total / total.max()


def mask_image(rng):
    """RGB: red = paint, green = bare metal; chips where the noise is high."""
    w, h = MASK_SIZE
    noise = smooth_noise(rng, (h, w))
    chipped = noise > np.quantile(noise, 1.0 - CHIPPED_FRACTION)
    rgb = np.zeros((h, w, 3), np.uint8)
    rgb[..., 0] = np.where(chipped, 0, 255)
    rgb[..., 1] = np.where(chipped, 255, 0)
    return Image.fromarray(rgb, "RGB")


def ramp_image():
    """One row: t = (u - 0.25) / 0.5 clamped, in the red channel."""
    u = (np.arange(RAMP_WIDTH) + 0.5) / RAMP_WIDTH
    t = np.clip((u - 0.25) / 0.5, 0.0, 1.0)
    rgb = np.zeros((1, RAMP_WIDTH, 3), np.uint8)
    rgb[0, :, 0] = np.round(255 * t).astype(np.uint8)
    return Image.fromarray(rgb, "RGB")


def tint_image():
    """Painted stripes (sRGB), slanted across the sphere."""
    w, h = TINT_SIZE
    colours = np.array([[230, 80, 60], [250, 250, 245], [60, 110, 210], [240, 200, 60]], np.uint8)
    y, x = np.mgrid[0:h, 0:w]
    stripe = ((x + 2 * y) // 24) % len(colours)
    return Image.fromarray(colours[stripe], "RGB")


def camera_node():
    elevation = math.radians(preview.CAMERA_ELEVATION_DEGREES)
    translation = [0.0, CAMERA_DISTANCE * math.sin(elevation), CAMERA_DISTANCE * math.cos(elevation)]
    half = -0.5 * elevation
    return {"name": "camera", "camera": 0, "translation": translation, "rotation": [math.sin(half), 0.0, 0.0, math.cos(half)]}


def build():
    buffer = BufferWriter()
    sphere = preview.uv_sphere(preview.SPHERE_RADIUS, 64, 32)
    preview.check_outward(sphere[0], sphere[3])
    ground = preview.ground_quad(preview.GROUND_HALF_SIZE, -preview.SPHERE_RADIUS)

    def primitive(mesh, material):
        positions, normals, uvs, triangles = mesh
        return buffer.primitive({"POSITION": positions, "NORMAL": normals, "TEXCOORD_0": uvs}, triangles, material)

    meshes = [{"name": name, "primitives": [primitive(sphere, i)]} for i, (name, *_rest) in enumerate(SPHERES)]
    meshes.append({"name": "ground", "primitives": [primitive(ground, len(SPHERES))]})
    nodes = [
        {"name": name, "mesh": i, "translation": [(i - 1) * SPACING, 0.0, 0.0]}
        for i, (name, *_rest) in enumerate(SPHERES)
    ]
    nodes += [
        {"name": "ground", "mesh": len(SPHERES)},
        camera_node(),
        {"name": "key-light", "translation": preview.KEY_POSITION, "extensions": {"KHR_lights_punctual": {"light": 0}}},
    ]
    materials = [
        {
            "name": name,
            "pbrMetallicRoughness": {"baseColorFactor": colour, "metallicFactor": metallic, "roughnessFactor": roughness},
            "extras": {"neural": neural},
        }
        for name, colour, metallic, roughness, neural in SPHERES
    ]
    materials.append({
        "name": "ground",
        "pbrMetallicRoughness": {"baseColorFactor": [preview.GROUND_ALBEDO] * 3 + [1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0},
        "extras": {"bsdf": "diffuse"},
    })
    clamp, repeat, linear = 33071, 10497, 9729
    gltf = {
        "asset": {"version": "2.0", "generator": "assets-scripts/make_neural_texture_scene.py"},
        "extensionsUsed": ["KHR_lights_punctual"],
        "scene": 0,
        "scenes": [{
            "name": "neural-texture",
            "nodes": list(range(len(nodes))),
            "extras": {"environment": {"image": "../material-preview/" + preview.ENVIRONMENT_IMAGE, "strength": preview.ENVIRONMENT_STRENGTH}},
        }],
        "nodes": nodes,
        "meshes": meshes,
        "materials": materials,
        "images": [{"uri": "mask.png"}, {"uri": "ramp.png"}, {"uri": "tint.png"}],
        "samplers": [
            {"magFilter": linear, "wrapS": repeat, "wrapT": clamp},
            {"magFilter": linear, "wrapS": clamp, "wrapT": clamp},
        ],
        "textures": [{"source": 0, "sampler": 0}, {"source": 1, "sampler": 1}, {"source": 2, "sampler": 0}],
        "cameras": [{
            "name": "camera",
            "type": "perspective",
            "perspective": {"yfov": math.radians(CAMERA_YFOV_DEGREES), "aspectRatio": ASPECT_RATIO, "znear": 0.01, "zfar": 1000.0},
        }],
        "extensions": {"KHR_lights_punctual": {"lights": [{
            "name": "key", "type": "point", "color": preview.KEY_COLOR, "intensity": preview.KEY_INTENSITY * preview.LUMENS_PER_WATT,
        }]}},
        **buffer.gltf_fields("scene.bin"),
    }
    return gltf, bytes(buffer.data)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("output", nargs="?", default=DEFAULT_SCENE_DIR, help="output directory")
    out_dir = os.path.normpath(parser.parse_args().output)
    os.makedirs(out_dir, exist_ok=True)
    rng = np.random.default_rng(SEED)
    gltf, data = build()
    with open(os.path.join(out_dir, "scene.bin"), "wb") as f:
        f.write(data)
    with open(os.path.join(out_dir, "scene.gltf"), "w") as f:
        json.dump(gltf, f, indent=1)
        f.write("\n")
    for name, image in [("mask.png", mask_image(rng)), ("ramp.png", ramp_image()), ("tint.png", tint_image())]:
        image.save(os.path.join(out_dir, name), optimize=True)
    print(f"wrote {out_dir}/scene.gltf + scene.bin ({len(data)} bytes), mask.png, ramp.png, tint.png")


if __name__ == "__main__":
    main()
