# SPDX-License-Identifier: MIT
"""Blender side of render-cli/tests/cli/blender_addon.rs: builds a scene by script, renders it
through the add-on and checks its errors. Run by the Rust test as

    blender -b --factory-startup --python-exit-code 1 --python plugins/blender/tests/addon_scene.py -- \\
        RENDER_BINARY LATENT_FILE OUT_DIR

The scene: a ground plane with a packed checker texture (Principled), a metal UV sphere
(Principled, metallic 1) called "Metal", a sun and a camera, 64 x 48 pixels. Writes to
OUT_DIR:
- bound.exr: the add-on's render with "Metal" bound to the code alum-bronze (4 spp, max
  depth 2, seed 7), its export kept in bound-export/ (scene.gltf, command.txt, render.exr);
- unbound.exr: the same with no code (Metal renders its glTF parameters);
- results.json: what the checks found, and "metal_box": the pixel box [x0, y0, x1, y1)
  (top-left origin, ends exclusive) holding the sphere's image;
- scene.blend: the bound scene, its sphere moving to the right in frame 2, set to write
  frames 1 and 2 to frame-0001.exr and frame-0002.exr (for `-a`);
- mix.gltf: a File > Export of the scene with the metal a mix of two codes weighted by a
  packed image and the ground Lambertian (a Diffuse BSDF).
Checks here (an AssertionError fails the run with exit code 1): the errors for Esc
(test_break simulated), a missing render binary, a missing latent file, an unknown code and
a mix without its image are one Blender error line each, and Blender goes on afterwards.
"""

import json
import math
import os
import sys

import addon_utils
import bpy
import numpy as np
from bpy_extras.object_utils import world_to_camera_view
from mathutils import Vector

WIDTH, HEIGHT = 64, 48
CODE = "alum-bronze"


def args():
    argv = sys.argv[sys.argv.index("--") + 1:]
    assert len(argv) == 3, "usage: ... -- RENDER_BINARY LATENT_FILE OUT_DIR"
    return [os.path.abspath(a) for a in argv]


def enable_addon():
    sys.path.insert(0, os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")))
    addon_utils.enable("neural_brdf_blender", default_set=True, handle_error=None)
    assert "neural_brdf_blender" in bpy.context.preferences.addons, "the add-on did not register"
    return sys.modules["neural_brdf_blender"]


def packed_image(name, rgba, non_color=False):
    h, w, _ = rgba.shape
    image = bpy.data.images.new(name, width=w, height=h, alpha=True)
    if non_color:
        image.colorspace_settings.name = "Non-Color"
    image.pixels.foreach_set(np.ascontiguousarray(rgba[::-1], dtype=np.float32).ravel())
    image.file_format = "PNG"
    image.pack()
    return image


def build_scene():
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj, do_unlink=True)
    scene = bpy.context.scene

    # Ground: a checker image texture on a Principled BSDF.
    u = (np.arange(64) + 0.5) / 64
    checker = ((np.floor(u * 8)[None, :] + np.floor(u * 8)[:, None]) % 2)[..., None]
    rgba = np.concatenate([0.2 + 0.6 * checker * np.array([1.0, 0.9, 0.7]), np.ones((64, 64, 1))], axis=-1)
    ground_mat = bpy.data.materials.new("Ground")
    ground_mat.use_nodes = True
    tex = ground_mat.node_tree.nodes.new("ShaderNodeTexImage")
    tex.image = packed_image("checker", rgba)
    principled = ground_mat.node_tree.nodes["Principled BSDF"]
    ground_mat.node_tree.links.new(tex.outputs["Color"], principled.inputs["Base Color"])
    principled.inputs["Roughness"].default_value = 0.8
    bpy.ops.mesh.primitive_plane_add(size=8.0, location=(0, 0, 0))
    ground = bpy.context.active_object
    ground.name = "Ground"
    ground.data.materials.append(ground_mat)

    # The metal sphere.
    metal = bpy.data.materials.new("Metal")
    metal.use_nodes = True
    p = metal.node_tree.nodes["Principled BSDF"]
    p.inputs["Base Color"].default_value = (0.9, 0.6, 0.4, 1.0)
    p.inputs["Metallic"].default_value = 1.0
    p.inputs["Roughness"].default_value = 0.3
    bpy.ops.mesh.primitive_uv_sphere_add(segments=32, ring_count=16, radius=0.6, location=(0.4, 0.6, 0.6))
    sphere = bpy.context.active_object
    sphere.name = "Metal"
    bpy.ops.object.shade_smooth()
    sphere.data.materials.append(metal)

    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", type="SUN"))
    sun.data.energy = 3.0
    sun.data.angle = 0.0
    sun.rotation_euler = (math.radians(40), math.radians(10), math.radians(30))
    scene.collection.objects.link(sun)

    camera = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    camera.location = (0.0, -5.0, 2.5)
    camera.rotation_euler = (Vector((0.1, 0.3, 0.6)) - camera.location).to_track_quat("-Z", "Y").to_euler()
    camera.data.angle = math.radians(45)
    scene.collection.objects.link(camera)
    scene.camera = camera

    world = scene.world or bpy.data.worlds.new("World")
    scene.world = world
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.1, 0.12, 0.15, 1.0)

    scene.render.engine = "NEURAL_BRDF"
    scene.render.resolution_x, scene.render.resolution_y = WIDTH, HEIGHT
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.frame_current = 1
    return scene, sphere, metal, ground_mat


def metal_box(scene, sphere):
    """The pixel box of the sphere's vertices as the camera sees them, one pixel of margin
    (the polygonal sphere's outline lies inside its vertices' box)."""
    bpy.context.view_layer.update()  # the matrices of the objects made above
    xs, ys = [], []
    for vertex in sphere.data.vertices:
        p = world_to_camera_view(scene, scene.camera, sphere.matrix_world @ vertex.co)
        xs.append(p.x * WIDTH)
        ys.append((1.0 - p.y) * HEIGHT)
    return [
        max(0, math.floor(min(xs)) - 1),
        max(0, math.floor(min(ys)) - 1),
        min(WIDTH, math.ceil(max(xs)) + 1),
        min(HEIGHT, math.ceil(max(ys)) + 1),
    ]


def close(a, b):
    return len(a) == len(b) and all(abs(x - y) < 1e-6 for x, y in zip(a, b))


def render_to(scene, path):
    scene.render.filepath = path
    return bpy.ops.render.render(write_still=True)


def render_error(scene, path):
    """Renders expecting an error; returns Blender's error text (the operator's exception)."""
    try:
        render_to(scene, path)
    except RuntimeError as e:
        return str(e).strip()
    raise AssertionError("the render did not fail")


def assert_one_error(message, *needles):
    lines = [line for line in message.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("Error: Neural BRDF: "), f"one error line expected: {message!r}"
    assert "Traceback" not in message, message
    for needle in needles:
        assert needle in message, f"{needle!r} not in {message!r}"


def main():
    render_binary, latent_file, out = args()
    os.makedirs(out, exist_ok=True)
    addon = enable_addon()
    scene, sphere, metal, ground_mat = build_scene()
    settings = scene.neural_brdf
    settings.render_path = render_binary
    settings.latent_file = latent_file
    settings.spp = 4
    settings.max_depth = 2
    settings.seed = 7
    results = {"metal_box": metal_box(scene, sphere)}

    # The latent file's codes, as the material panel lists them.
    codes, error = addon.runner.latent_codes(settings)
    assert error is None and CODE in codes, (codes, error)
    results["codes"] = len(codes)

    # Bound and unbound renders, their exports kept.
    metal.neural_brdf.code = CODE
    settings.export_dir = os.path.join(out, "bound-export")
    assert render_to(scene, os.path.join(out, "bound.exr")) == {'FINISHED'}
    metal.neural_brdf.code = ""
    settings.export_dir = os.path.join(out, "unbound-export")
    assert render_to(scene, os.path.join(out, "unbound.exr")) == {'FINISHED'}
    with open(os.path.join(out, "bound-export", "scene.gltf")) as f:
        gltf = json.load(f)
    extras = {m["name"]: m.get("extras") for m in gltf["materials"]}
    assert extras["Metal"] == {"neural": CODE}, extras
    assert "neural_brdf" not in json.dumps(gltf), "the add-on's settings leaked into the glTF"
    assert close(gltf["scenes"][0]["extras"]["environment"]["color"], [0.1, 0.12, 0.15]), gltf["scenes"][0]

    # Esc: esc_pressed (the engine's test_break) says so once the render has started; the image so far is kept.
    metal.neural_brdf.code = CODE
    settings.export_dir = ""
    engine_class = addon.engine.NeuralBrdfRenderEngine
    calls = {"n": 0}

    def esc_pressed(self):
        calls["n"] += 1
        return calls["n"] >= 2  # the first call comes after the export, the second once render runs

    original, engine_class.esc_pressed = engine_class.esc_pressed, esc_pressed
    try:
        message = render_error(scene, os.path.join(out, "esc.exr"))
    finally:
        engine_class.esc_pressed = original
    assert_one_error(message, "cancelled (Esc)")
    results["esc"] = message

    # A missing binary, a missing latent file, an unknown code: one line each.
    settings.render_path = os.path.join(out, "no-such-render")
    message = render_error(scene, os.path.join(out, "error.exr"))
    assert_one_error(message, "no-such-render: no such file")
    results["missing_binary"] = message
    settings.render_path = render_binary
    settings.latent_file = os.path.join(out, "missing-latent.bin")
    message = render_error(scene, os.path.join(out, "error.exr"))
    assert_one_error(message, "missing-latent.bin")
    results["missing_latent"] = message
    settings.latent_file = latent_file
    metal.neural_brdf.code = "no-such-code"
    message = render_error(scene, os.path.join(out, "error.exr"))
    assert_one_error(message, "no-such-code", CODE)
    results["unknown_code"] = message

    # Blender carries on: a mix of two codes by a packed weights image, and a Lambertian
    # ground, exported by hand (File > Export > glTF 2.0) with the add-on enabled.
    metal.neural_brdf.mode = 'MIX'
    metal.neural_brdf.code = CODE
    metal.neural_brdf.code_b = codes[1] if codes[0] == CODE else codes[0]
    message = render_error(scene, os.path.join(out, "error.exr"))  # no weights image yet
    assert_one_error(message, "material 'Metal'", "weights needs an image")
    results["incomplete_binding"] = message
    v = (np.arange(16) + 0.5) / 16
    red = np.broadcast_to((v[None, :] < 0.5).astype(float), (16, 16))
    weights = np.stack([red, 1.0 - red, np.zeros_like(red), np.ones_like(red)], axis=-1)
    metal.neural_brdf.weights = packed_image("mix-weights", weights, non_color=True).name
    nodes = ground_mat.node_tree.nodes
    diffuse = nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Color"].default_value = (0.5, 0.4, 0.3, 1.0)
    ground_mat.node_tree.links.new(diffuse.outputs["BSDF"], nodes["Material Output"].inputs["Surface"])
    bpy.ops.export_scene.gltf(filepath=os.path.join(out, "mix.gltf"), export_format='GLTF_SEPARATE', export_extras=True,
                              export_cameras=True, export_lights=True)
    with open(os.path.join(out, "mix.gltf")) as f:
        gltf = json.load(f)
    extras = {m["name"]: m.get("extras") for m in gltf["materials"]}
    assert extras["Metal"]["neural"]["mix"] == [CODE, metal.neural_brdf.code_b], extras
    texture = extras["Metal"]["neural"]["weights"]
    assert gltf["images"][gltf["textures"][texture["index"]]["source"]]["uri"].startswith("data:image/png;base64,")
    assert extras["Ground"] == {"bsdf": "diffuse"}, extras
    ground = next(m for m in gltf["materials"] if m["name"] == "Ground")
    assert close(ground["pbrMetallicRoughness"]["baseColorFactor"][:3], [0.5, 0.4, 0.3]), ground

    # The bound scene for `blender -b scene.blend -E NEURAL_BRDF -a`: frame 1 as above, in
    # frame 2 the sphere has moved 0.5 m to the right.
    metal.neural_brdf.mode = 'CODE'
    sphere.keyframe_insert("location", frame=1)
    sphere.location.x += 0.5
    sphere.keyframe_insert("location", frame=2)
    scene.frame_start, scene.frame_end = 1, 2
    scene.frame_set(1)
    ground_mat.node_tree.links.new(nodes["Principled BSDF"].outputs["BSDF"], nodes["Material Output"].inputs["Surface"])
    settings.export_dir = os.path.join(out, "frame-export")
    scene.render.engine = "BLENDER_EEVEE"  # `-E NEURAL_BRDF` chooses it
    scene.render.filepath = os.path.join(out, "frame-")
    bpy.ops.wm.save_as_mainfile(filepath=os.path.join(out, "scene.blend"))

    with open(os.path.join(out, "results.json"), "w") as f:
        json.dump(results, f, indent=1)
    print("addon_scene.py: all checks passed")


main()
# Blender exits with code 1 after a render that reported an error, as the checks above make
# five do on purpose; they passed.
sys.exit(0)
