"""Build a glass scene in Blender, export it with Blender's own glTF exporter and (optionally)
render the scene as built with Cycles: the reference for our KHR_materials_transmission /
KHR_materials_volume support.

    blender -b --factory-startup --python assets-scripts/make_glass_scene.py -- \\
        [OUTPUT_DIR] [--reference OUT.exr] [--spp N] [--resolution WxH] [--max-bounces B]
        [--seed S] [--threads T] [--lambert-ground]

OUTPUT_DIR defaults to data/glass-scene/ (git-ignored). Writes OUTPUT_DIR/scene.gltf,
scene.bin, the ground texture PNG and OUTPUT_DIR/scene.blend (the scene as built, before any
render set-up). With --reference it then renders that same Blender scene (not a re-import of the
glTF: nothing the importer could drop) with Cycles into OUT.exr (linear) and OUT.png. Defaults:
1024 spp, 256 x 256, max bounces 32 (every bounce kind). Our renderer on the export:

    target/release/render OUTPUT_DIR/scene.gltf --resolution 256x256 --spp 1024 \\
        --max-depth 34 -o ours.exr

(our --max-depth counts path segments, Cycles' max bounces count bounces after the first hit:
depth D = bounces D - 2.) Compare with `compare_cycles.py ours.exr OUT.exr --regions glass`;
the measured table is in docs/gltf-assets.md, "Glass against Cycles".

The scene (Blender Z-up; the exporter writes glTF's Y-up), made the way a user makes one:
  * ground plane 20 m x 20 m, Principled (roughness 0.8) with a stone-tile base-colour image
    (make_blender_scene.tile_textures' procedural tiles baked to a packed 8-bit sRGB PNG;
    UVs x 2.5: 1 m tiles), no normal map;
  * a clear glass sphere, radius 1 m: Principled BSDF Transmission 1, IOR 1.5, Roughness 0,
    base colour white, GGX; a "glTF Material Output" node group (the exporter's own
    create_settings_group, what its Add > Output menu entry makes) with Thickness 2 (the
    diameter), so the exporter writes KHR_materials_volume {thicknessFactor: 2}: a solid
    sphere. Without that node Blender 3.4's exporter writes no volume and the glTF surface
    is thin-walled (a soap bubble), while Cycles always renders a closed mesh as a solid.
    IOR 1.5 is glTF's default, so the exporter writes no KHR_materials_ior;
  * a rough glass sphere, radius 0.7 m: the same with Roughness 0.3, Thickness 1.4;
  * three metal spheres, linked duplicates of one mesh (obj.copy(): one glTF mesh, three
    nodes): Principled Metallic 1, Roughness 0.25, a gold base colour;
  * a Sun of 3 W/m^2 (exported as 2049 lx) at 35 deg elevation from behind on the left, so
    the shadows fall toward the camera; its angle is 0 (glTF suns are infinitely distant
    points; with a disc Cycles would find the sun through smooth glass, a caustic no path
    tracer reaches for a point sun);
  * a perspective camera, 40 deg field of view, aspect 1;
  * a constant sky: World Background (0.12, 0.16, 0.24), strength 1, and the same colour as a
    scene custom property "environment" = {"color": [...]} that the exporter writes (with
    export_extras) into scenes[0].extras, where our renderer reads its environment.

--lambert-ground (a diagnostic, not how a user would make the scene): the ground is Lambertian
in both renderers, so that what differs is the glass and the metal: the ground material gets
a custom property bsdf = "diffuse", which the exporter writes into its extras (our renderer's
Lambert, base colour x texture), and for the Cycles render, after the export, its Principled
BSDF is replaced by a Diffuse BSDF (roughness 0: Lambert) fed by the same texture.

Spheres are built from arrays with exact normals (make_blender_scene.add_uv_sphere): the
export is deterministic (byte-identical files run after run).

Cycles set-up for --reference (cycles_reference.setup_cycles): CPU path tracing, fixed seed, no
adaptive sampling, no denoising, no clamping, blur_glossy 0, caustics reflective and
refractive on, light threshold 0, box pixel filter 1 px; max, diffuse, glossy and
transmission bounces all --max-bounces, transparent 16, volume 0. Before rendering, the 8-bit
sRGB ground texture is replaced by a linear float copy (cycles_reference.linearize_srgb_images:
Cycles would filter sRGB-encoded values, glTF filters linear ones).

Expected noise in Blender's log: "ERROR: Draco mesh compression is not available".
"""

import math
import os
import sys

import bpy
import numpy as np
from mathutils import Vector

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import make_blender_scene as mbs  # noqa: E402  (helpers: textures, spheres, materials)

SEED = 20240612
SKY = (0.12, 0.16, 0.24)


def usage(message=None):
    if message:
        print("make_glass_scene.py: " + message, file=sys.stderr)
    sys.exit("usage: blender -b --factory-startup --python assets-scripts/make_glass_scene.py "
             "-- [OUTPUT_DIR] [--reference OUT.exr] [--spp N] [--resolution WxH] "
             "[--max-bounces B] [--seed S] [--threads T] [--lambert-ground]")


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    opts = {"out_dir": os.path.join(os.path.dirname(HERE), "data", "glass-scene"),
            "cycles": None, "spp": 1024, "resolution": (256, 256), "max_bounces": 32,
            "seed": 0, "threads": 0, "filter_width": 1.0, "lambert_ground": False}
    positional = []
    i = 0
    while i < len(argv):
        a = argv[i]
        if a in ("--reference", "--spp", "--resolution", "--max-bounces", "--seed", "--threads"):
            if i + 1 >= len(argv):
                usage(a + " needs a value")
            v = argv[i + 1]
            try:
                if a == "--reference":
                    opts["cycles"] = os.path.abspath(v)
                elif a == "--resolution":
                    w, h = v.lower().split("x")
                    opts["resolution"] = (int(w), int(h))
                else:
                    opts[a[2:].replace("-", "_")] = int(v)
            except ValueError:
                usage("bad value for " + a)
            i += 2
        elif a == "--lambert-ground":
            opts["lambert_ground"] = True
            i += 1
        elif a.startswith("-"):
            usage("unknown option " + a)
        else:
            positional.append(a)
            i += 1
    if len(positional) > 1:
        usage()
    if positional:
        opts["out_dir"] = os.path.abspath(positional[0])
    if opts["cycles"] and not opts["cycles"].lower().endswith(".exr"):
        usage("--reference takes an .exr path")
    return opts


# ---------------------------------------------------------------- materials

def tiles_material(base_img, lambert):
    mat, tree, bsdf = mbs.principled_material("Tiles")
    tex = mbs.image_node(tree, base_img, -600, 300)
    tree.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    bsdf.inputs["Roughness"].default_value = 0.8
    bsdf.inputs["Metallic"].default_value = 0.0
    bsdf.distribution = "GGX"
    if lambert:
        mat["bsdf"] = "diffuse"  # -> materials[].extras.bsdf: our renderer's Lambert
    return mat


def make_ground_lambertian():
    """For the Cycles render with --lambert-ground: Principled -> Diffuse BSDF (roughness 0),
    same base colour input."""
    mat = bpy.data.materials["Tiles"]
    tree = mat.node_tree
    principled = tree.nodes["Principled BSDF"]
    diffuse = tree.nodes.new("ShaderNodeBsdfDiffuse")
    diffuse.inputs["Roughness"].default_value = 0.0
    tree.links.new(principled.inputs["Base Color"].links[0].from_socket, diffuse.inputs["Color"])
    tree.links.new(diffuse.outputs["BSDF"], tree.nodes["Material Output"].inputs["Surface"])
    tree.nodes.remove(principled)
    print("make_glass_scene: ground material -> Diffuse BSDF (Lambert) for the Cycles render")


def glass_material(name, roughness, thickness):
    """Principled glass plus the exporter's "glTF Material Output" group with a Thickness,
    which makes the exporter write KHR_materials_volume (a solid, not a thin wall)."""
    from io_scene_gltf2.blender.com.gltf2_blender_material_helpers import (
        create_settings_group, get_gltf_node_name)
    mat, tree, bsdf = mbs.principled_material(name)
    bsdf.distribution = "GGX"
    bsdf.inputs["Base Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    bsdf.inputs["Metallic"].default_value = 0.0
    bsdf.inputs["Roughness"].default_value = roughness
    bsdf.inputs["Transmission"].default_value = 1.0
    bsdf.inputs["IOR"].default_value = 1.5
    group_name = get_gltf_node_name()  # "glTF Material Output"
    group = bpy.data.node_groups.get(group_name) or create_settings_group(group_name)
    node = tree.nodes.new("ShaderNodeGroup")
    node.node_tree = group
    node.location = (0, -700)
    node.inputs["Thickness"].default_value = thickness
    return mat


def metal_material():
    mat, tree, bsdf = mbs.principled_material("Gold")
    bsdf.distribution = "GGX"
    bsdf.inputs["Base Color"].default_value = (0.95, 0.72, 0.35, 1.0)
    bsdf.inputs["Metallic"].default_value = 1.0
    bsdf.inputs["Roughness"].default_value = 0.25
    return mat


# ---------------------------------------------------------------- scene

def build(out_dir, resolution, lambert_ground=False):
    rng = np.random.default_rng(SEED)
    mbs.clear_scene()
    for group in list(bpy.data.node_groups):
        bpy.data.node_groups.remove(group)
    scene = bpy.context.scene

    base, _normal = mbs.tile_textures(rng)
    tiles_img = mbs.make_image("glass_tiles_basecolor", base)

    ground = mbs.add_primitive(bpy.ops.mesh.primitive_plane_add, "Ground",
                               tiles_material(tiles_img, lambert_ground), size=20.0,
                               location=(0, 0, 0))
    uv = ground.data.uv_layers.active.data
    coords = np.empty(2 * len(uv), dtype=np.float32)
    uv.foreach_get("uv", coords)
    uv.foreach_set("uv", coords * 2.5)

    mbs.add_uv_sphere("ClearGlass", glass_material("ClearGlass", 0.0, 2.0),
                      segments=128, rings=64, radius=1.0, location=(0.0, 0.0, 1.0))
    mbs.add_uv_sphere("RoughGlass", glass_material("RoughGlass", 0.3, 1.4),
                      segments=96, rings=48, radius=0.7, location=(-2.3, 0.6, 0.7))

    gold = mbs.add_uv_sphere("Gold.0", metal_material(), segments=64, rings=32, radius=0.55,
                             location=(-0.7, 2.6, 0.55))
    for i, loc in enumerate([(1.2, 2.0, 0.55), (2.9, 3.4, 0.55)], start=1):
        dup = mbs.link(gold.copy())  # linked duplicate: shares gold.data
        dup.name = f"Gold.{i}"
        dup.location = loc

    sun_data = bpy.data.lights.new("Sun", type="SUN")
    sun_data.energy = 3.0  # W/m^2
    sun_data.angle = 0.0
    sun = mbs.link(bpy.data.objects.new("Sun", sun_data))
    sun.location = (-5, 5, 6)
    elevation, azimuth = math.radians(35), math.radians(130)  # from behind on the left
    to_light = Vector((math.cos(elevation) * math.cos(azimuth),
                       math.cos(elevation) * math.sin(azimuth), math.sin(elevation)))
    sun.rotation_euler = (-to_light).to_track_quat("-Z", "Y").to_euler()

    cam_data = bpy.data.cameras.new("Camera")
    cam_data.type = "PERSP"
    cam_data.sensor_fit = "AUTO"
    cam_data.angle = math.radians(40.0)
    cam_data.clip_start = 0.1
    cam_data.clip_end = 100.0
    cam = mbs.link(bpy.data.objects.new("Camera", cam_data))
    cam.location = (0.6, -7.2, 2.7)
    mbs.look_at(cam, (-0.1, 0.8, 0.75))
    scene.camera = cam
    scene.render.resolution_x, scene.render.resolution_y = resolution
    scene.render.resolution_percentage = 100

    world = bpy.data.worlds.new("World") if scene.world is None else scene.world
    scene.world = world
    world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (*SKY, 1.0)
    bg.inputs["Strength"].default_value = 1.0
    scene["environment"] = {"color": list(SKY)}  # -> scenes[0].extras (export_extras)

    bpy.context.view_layer.update()

    os.makedirs(out_dir, exist_ok=True)
    path = os.path.join(out_dir, "scene.gltf")
    bpy.ops.export_scene.gltf(
        filepath=path,
        export_format="GLTF_SEPARATE",
        export_lights=True,
        export_cameras=True,
        export_extras=True,
        export_yup=True,
        export_image_format="AUTO",
        export_apply=False,
    )
    print(f"make_glass_scene: wrote {path}")
    blend = os.path.join(out_dir, "scene.blend")
    bpy.context.preferences.filepaths.save_version = 0  # no scene.blend1 backups
    bpy.ops.wm.save_as_mainfile(filepath=blend, compress=False)
    print(f"make_glass_scene: wrote {blend}")


def render_cycles(opts):
    import cycles_reference as cr
    scene = bpy.context.scene
    width, height = opts["resolution"]
    cr.setup_cycles(scene, opts, width, height)
    if opts["lambert_ground"]:
        make_ground_lambertian()
    cr.linearize_srgb_images()
    print("cycles: %dx%d, %d spp, bounces max %d diffuse %d glossy %d transmission %d, "
          "caustics reflective %s refractive %s, blur_glossy %g, clamp %g/%g, filter %s %g px" % (
              width, height, scene.cycles.samples, scene.cycles.max_bounces,
              scene.cycles.diffuse_bounces, scene.cycles.glossy_bounces,
              scene.cycles.transmission_bounces, scene.cycles.caustics_reflective,
              scene.cycles.caustics_refractive, scene.cycles.blur_glossy,
              scene.cycles.sample_clamp_direct, scene.cycles.sample_clamp_indirect,
              scene.cycles.pixel_filter_type, scene.cycles.filter_width))
    os.makedirs(os.path.dirname(opts["cycles"]) or ".", exist_ok=True)
    png = cr.render_to(scene, opts["cycles"])
    print("make_glass_scene: wrote %s and %s (Cycles %s)" % (opts["cycles"], png,
                                                            bpy.app.version_string))


if __name__ == "__main__":
    opts = parse_args()
    build(opts["out_dir"], opts["resolution"], opts["lambert_ground"])
    if opts["cycles"]:
        render_cycles(opts)
