"""Renders a Lambertian-and-metal scene built in Blender through the Neural BRDF add-on and
with Cycles, timing both, for assets-scripts/compare_cycles.py to compare region by region.

    blender -b --factory-startup --python assets-scripts/addon_vs_cycles.py -- OUT_DIR \\
        [--render target/release/render] [--spp 512] [--seed 0] [--runs 3] [--size 256]
    blender -b --factory-startup --python assets-scripts/addon_vs_cycles.py -- OUT_DIR \
        --showcase docs/images/blender-addon.png [--spp 256] [--size 512]
    python3 assets-scripts/compare_cycles.py OUT_DIR/ours-s0.exr OUT_DIR/cycles-s0.exr \\
        --regions OUT_DIR/regions.json [--repeat OUT_DIR/ours-s1.exr OUT_DIR/cycles-s1.exr] \\
        --png docs/images/blender-addon-vs-cycles.png

Writes OUT_DIR/ours-sSEED.exr (through the add-on: F12's path, export + `render` + load),
OUT_DIR/cycles-sSEED.exr, OUT_DIR/regions.json (boxes inside each object and shadow, from
the camera's projection, on the 256 x 256 grid compare_cycles.py takes), OUT_DIR/scene.blend,
and prints the seconds of `--runs` renders of each (min / median / max): ours as export,
`render` and the whole F12 (the add-on's export, run and load), Cycles' whole F12.

`--showcase PNG` renders the scene through the add-on only, with latent codes of
scenes/materials/latent.bin bound to the spheres (red-metallic-paint, gold-metallic-paint,
chrome), into PNG (sRGB, 'Standard' view transform: clamped, not tone-mapped).

The scene (Blender Z-up): a ground plane 40 m wide and a wall-like block behind, Lambertian (Diffuse
BSDF: the add-on exports it as {"bsdf": "diffuse"}, Cycles renders it at roughness 0, i.e.
Lambertian); a Lambertian red sphere; two metal spheres (Principled BSDF, metallic 1: gold
at roughness 0.35, steel at 0.15; ours: glTF metallic-roughness, GGX with Schlick's Fresnel,
Cycles 3.4: Principled v1 GGX, whose metal Fresnel is not Schlick's); a 3 W/m^2 sun at 40
degrees (angle 0: glTF suns are points) and a constant sky (0.30, 0.40, 0.60), which the
add-on writes as the environment. Settings as assets-scripts/cycles_reference.py: our
--max-depth 8 = Cycles' bounces 6 of every kind, 1 px box filter, no clamping, no glossy
blur, caustics on, adaptive sampling and denoising off, the same seed.
"""

import json
import math
import os
import statistics
import sys
import time

import addon_utils
import bpy
from bpy_extras.object_utils import world_to_camera_view
from mathutils import Vector

REPO = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
GRID = 256  # compare_cycles.py's region grid


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    opts = {"render": os.path.join(REPO, "target", "release", "render"), "spp": 512, "seed": 0, "runs": 3, "size": 256,
            "showcase": None}
    out = None
    i = 0
    while i < len(argv):
        key = argv[i][2:] if argv[i].startswith("--") else None
        if key in opts:
            if i + 1 >= len(argv):
                sys.exit(f"addon_vs_cycles.py: --{key} needs a value")
            opts[key] = argv[i + 1] if key in ("render", "showcase") else int(argv[i + 1])
            i += 2
        elif key is None and out is None:
            out = os.path.abspath(argv[i])
            i += 1
        else:
            sys.exit(__doc__.split("\n\n")[1])
    if out is None:
        sys.exit(__doc__.split("\n\n")[1])
    return out, opts


def diffuse_material(name, colour):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    nodes = m.node_tree.nodes
    nodes.remove(nodes["Principled BSDF"])
    d = nodes.new("ShaderNodeBsdfDiffuse")
    d.inputs["Color"].default_value = (*colour, 1.0)
    d.inputs["Roughness"].default_value = 0.0
    m.node_tree.links.new(d.outputs["BSDF"], nodes["Material Output"].inputs["Surface"])
    return m


def metal_material(name, colour, roughness):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    p = m.node_tree.nodes["Principled BSDF"]
    p.inputs["Base Color"].default_value = (*colour, 1.0)
    p.inputs["Metallic"].default_value = 1.0
    p.inputs["Roughness"].default_value = roughness
    return m


def sphere(name, material, location, radius=0.7):
    bpy.ops.mesh.primitive_uv_sphere_add(segments=64, ring_count=32, radius=radius, location=location)
    obj = bpy.context.active_object
    obj.name = name
    bpy.ops.object.shade_smooth()
    obj.data.materials.append(material)
    return obj


def build(size):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    bpy.ops.mesh.primitive_plane_add(size=40.0)
    bpy.context.active_object.name = "Ground"
    bpy.context.active_object.data.materials.append(diffuse_material("Ground", (0.45, 0.45, 0.45)))
    bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0.3, 2.6, 1.2))
    block = bpy.context.active_object
    block.name = "Block"
    block.scale = (4.5, 0.6, 2.4)
    block.data.materials.append(diffuse_material("Block", (0.25, 0.55, 0.35)))
    spheres = {
        "red Lambertian sphere": sphere("Red", diffuse_material("Red", (0.7, 0.2, 0.15)), (-1.7, 0.0, 0.7)),
        "gold sphere (roughness 0.35)": sphere("Gold", metal_material("Gold", (1.0, 0.77, 0.34), 0.35), (0.0, 0.6, 0.7)),
        "steel sphere (roughness 0.15)": sphere("Steel", metal_material("Steel", (0.56, 0.57, 0.58), 0.15), (1.7, 0.0, 0.7)),
    }

    sun = bpy.data.objects.new("Sun", bpy.data.lights.new("Sun", type="SUN"))
    sun.data.energy = 3.0
    sun.data.angle = 0.0
    elevation, azimuth = math.radians(40), math.radians(-60)
    to_sun = Vector((math.cos(elevation) * math.cos(azimuth), math.cos(elevation) * math.sin(azimuth), math.sin(elevation)))
    sun.rotation_euler = (-to_sun).to_track_quat("-Z", "Y").to_euler()
    scene.collection.objects.link(sun)

    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.location = (0.0, -6.5, 2.6)
    cam.rotation_euler = (Vector((0.0, 0.6, 0.6)) - cam.location).to_track_quat("-Z", "Y").to_euler()
    cam.data.angle = math.radians(50)
    scene.collection.objects.link(cam)
    scene.camera = cam

    world = bpy.data.worlds.new("World")
    scene.world = world
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0.30, 0.40, 0.60, 1.0)
    world.node_tree.nodes["Background"].inputs["Strength"].default_value = 1.0

    r = scene.render
    r.resolution_x = r.resolution_y = size
    r.resolution_percentage = 100
    r.image_settings.file_format = "OPEN_EXR"
    r.image_settings.color_depth = "32"
    bpy.context.view_layer.update()
    return scene, spheres, to_sun


def pixel(scene, point):
    p = world_to_camera_view(scene, scene.camera, point)
    return p.x * GRID, (1.0 - p.y) * GRID


def box(centre, half, name):
    x, y = centre
    return [name, round(x - half), round(y - half), round(x + half), round(y + half)]


def regions(scene, spheres, to_sun):
    """Boxes on the 256 grid: inside each sphere (half the projected radius), the middle of
    each sphere's shadow on the ground, the open ground, the block and the sky."""
    out = [["sky", 0, 0, GRID, 20]]
    cam_right = scene.camera.matrix_world.to_3x3() @ Vector((1.0, 0.0, 0.0))
    for name, obj in spheres.items():
        c = obj.location
        radius = obj.dimensions.x / 2
        centre = pixel(scene, c)
        r_px = abs(pixel(scene, c + cam_right * radius)[0] - centre[0])
        out.append(box(centre, 0.5 * r_px, name))
        # The shadow's centre: the sphere's centre moved along the sun's direction to z = 0.
        shadow = c - to_sun * (c.z / to_sun.z)
        out.append(box(pixel(scene, shadow), 0.25 * r_px, f"{name}'s shadow"))
    out.append(box(pixel(scene, Vector((-1.2, -2.5, 0.0))), 10, "open ground (sunlit)"))
    out.append(box(pixel(scene, Vector((-0.9, 2.3, 1.9))), 6, "block (front face, above the spheres)"))
    return out


def setup_ours(scene, render, spp, seed):
    scene.render.engine = "NEURAL_BRDF"
    s = scene.neural_brdf
    s.render_path, s.latent_file, s.spp, s.max_depth, s.seed = render, "", spp, 8, seed


def setup_cycles(scene, spp, seed):
    scene.render.engine = "CYCLES"
    c = scene.cycles
    c.device, c.samples, c.seed, c.use_animated_seed = "CPU", spp, seed, False
    c.use_adaptive_sampling = c.use_denoising = False
    c.sample_clamp_direct = c.sample_clamp_indirect = c.blur_glossy = c.light_sampling_threshold = 0.0
    c.caustics_reflective = c.caustics_refractive = True
    c.max_bounces = c.diffuse_bounces = c.glossy_bounces = c.transmission_bounces = 6
    c.volume_bounces, c.transparent_max_bounces = 0, 16
    c.pixel_filter_type, c.filter_width = "BOX", 1.0
    scene.render.film_transparent = False


def timed_renders(scene, path, runs, engine_module=None):
    times = []
    parts = []
    for _ in range(runs):
        scene.render.filepath = path
        start = time.perf_counter()
        bpy.ops.render.render(write_still=True)
        times.append(time.perf_counter() - start)
        if engine_module is not None:
            parts.append(dict(engine_module.last_timings))
    return times, parts


def spread(values):
    return f"{min(values):.1f} / {statistics.median(values):.1f} / {max(values):.1f}"


def main():
    out, opts = parse_args()
    os.makedirs(out, exist_ok=True)
    scene, spheres, to_sun = build(opts["size"])  # factory settings first: they disable add-ons
    sys.path.insert(0, os.path.join(REPO, "plugins", "blender"))
    addon_utils.enable("neural_brdf_blender", default_set=True, handle_error=None)
    addon = sys.modules["neural_brdf_blender"]
    with open(os.path.join(out, "regions.json"), "w") as f:
        json.dump(regions(scene, spheres, to_sun), f, indent=1)
    bpy.ops.wm.save_as_mainfile(filepath=os.path.join(out, "scene.blend"))

    seed, spp, runs = opts["seed"], opts["spp"], opts["runs"]
    if opts["showcase"]:
        setup_ours(scene, os.path.abspath(opts["render"]), spp, seed)
        scene.neural_brdf.latent_file = os.path.join(REPO, "scenes", "materials", "latent.bin")
        for material, code in (("Red", "red-metallic-paint"), ("Gold", "gold-metallic-paint"), ("Steel", "chrome")):
            bpy.data.materials[material].neural_brdf.code = code
        scene.render.image_settings.file_format = "PNG"
        scene.render.image_settings.color_depth = "8"
        scene.view_settings.view_transform = "Standard"
        scene.view_settings.look = "None"
        scene.render.filepath = os.path.abspath(opts["showcase"])
        bpy.ops.render.render(write_still=True)
        return
    setup_ours(scene, os.path.abspath(opts["render"]), spp, seed)
    ours, parts = timed_renders(scene, os.path.join(out, f"ours-s{seed}.exr"), runs, addon.engine)
    setup_cycles(scene, spp, seed)
    cycles, _ = timed_renders(scene, os.path.join(out, f"cycles-s{seed}.exr"), runs)
    print(f"\n{opts['size']}x{opts['size']}, {spp} spp, seed {seed}, {runs} runs each, seconds min / median / max:")
    print(f"  ours: export {spread([p['export'] for p in parts])}, render {spread([p['render'] for p in parts])}, "
          f"F12 in all {spread(ours)}")
    print(f"  Cycles: F12 in all {spread(cycles)}")


main()
