"""Build a small test scene in Blender and export it with Blender's own glTF exporter.

A real Blender export, to check that the renderer reads what Blender writes (the other
assets-scripts hand-write their glTF). Run with Debian's `blender` package (3.4.x; needs
`python3-numpy` too, which the glTF exporter also imports); CI never runs this:

    blender --background --factory-startup --python assets-scripts/make_blender_scene.py -- [OUTPUT_DIR]

OUTPUT_DIR defaults to data/blender-scene/ (git-ignored). Writes OUTPUT_DIR/scene.gltf,
scene.bin and the PNG textures (export format GLTF_SEPARATE).

The scene (Blender is Z-up; the exporter converts to glTF's Y-up):
  * ground plane 20 m x 20 m: procedural tile base-colour texture (sRGB; UVs scaled so it
    repeats 2.5 times: 1 m tiles, REPEAT wrapping) and a tangent-space normal map of the tile
    grooves (Non-Color image -> Normal Map node -> Principled Normal -> normalTexture); no
    tangents are exported (export_tangents=False), so the loader must make its own;
  * a smooth UV sphere whose roughness and metallic come from one image through a Separate
    Color node (G -> Roughness, B -> Metallic): the exporter packs it into a
    metallicRoughnessTexture (8 bands alternating metal / dielectric);
  * twelve cubes that are linked duplicates (one mesh data-block, obj.copy() sharing .data)
    at different transforms: the exporter writes twelve nodes sharing one mesh;
  * a cut-out plane in front of the sphere: RGBA base-colour texture with round holes
    (alpha 0), image Alpha -> Principled Alpha, blend_method CLIP, alpha_threshold 0.5
    -> alphaMode MASK, alphaCutoff 0.5; double-sided;
  * a Sun light (3 W/m^2; its 0.5 deg angle has no glTF equivalent) at a raking 25 deg
    elevation from the front right, and a warm 60 W point light;
    the exporter's default lighting mode (SPEC) writes photometric units (x 683 lm/W, the
    point light also / 4 pi): 2049 lx and about 3261 cd;
  * a perspective camera, 40 deg field of view, 512 x 512 render resolution (aspect 1),
    set as the scene camera; a dim constant world colour (glTF has no world; not exported).

All materials come out doubleSided (Blender's default: no backface culling). Expected noise
in Blender's log: "ERROR: Draco mesh compression is not available" (Debian ships no Draco; not
used) and twice "More than one shader node tex image used for a texture" (the same image node
feeds Roughness + Metallic, and Base Color + Alpha).

Deterministic: fixed numpy seed; the sphere is built from arrays with exact custom normals
(see add_uv_sphere). 24 runs (some two at a time) wrote byte-identical files with Blender 3.4.1.
"""

import math
import os
import sys

import bpy
import numpy as np
from mathutils import Euler, Vector

SEED = 20240611
TEX = 256  # texture size (square)


def parse_args():
    """(output directory, whether to export Blender's own tangents). With --tangents the
    exporter writes Blender's MikkTSpace tangents as TANGENT, for comparing them with the
    tangents the renderer computes for the same file without them."""
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    tangents = "--tangents" in argv
    argv = [a for a in argv if a != "--tangents"]
    if len(argv) > 1 or any(a.startswith("-") for a in argv):
        sys.exit("usage: blender --background --factory-startup --python "
                 "assets-scripts/make_blender_scene.py -- [--tangents] [OUTPUT_DIR]")
    if argv:
        return os.path.abspath(argv[0]), tangents
    repo = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    return os.path.join(repo, "data", "blender-scene"), tangents


def clear_scene():
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj, do_unlink=True)
    for coll in (bpy.data.meshes, bpy.data.materials, bpy.data.lights, bpy.data.cameras,
                 bpy.data.images, bpy.data.textures):
        for block in list(coll):
            coll.remove(block)


# ---------------------------------------------------------------- textures (numpy -> packed PNG)

def make_image(name, rgba, non_color=False):
    """rgba: (H, W, 4) float array in [0, 1], row 0 = top. Packed into the .blend as PNG."""
    h, w, _ = rgba.shape
    img = bpy.data.images.new(name, width=w, height=h, alpha=True, float_buffer=False)
    if non_color:
        img.colorspace_settings.name = "Non-Color"
    # Blender's pixel rows run bottom to top.
    img.pixels.foreach_set(np.ascontiguousarray(rgba[::-1], dtype=np.float32).ravel())
    img.file_format = "PNG"
    img.pack()
    return img


def tile_textures(rng):
    """Ground: 8 x 8 stone tiles with grooves -> (base colour, tangent-space normal map)."""
    n = TEX
    tiles = 8
    u = (np.arange(n) + 0.5) / n
    uu, vv = np.meshgrid(u, u)  # vv: image row (top = 0), the normal map's v is handled below
    fu, fv = (uu * tiles) % 1.0, (vv * tiles) % 1.0
    # height: 1 on the tile, falling to 0 in a groove of half-width g at the tile edges
    g = 0.1
    du = np.minimum(fu, 1.0 - fu)
    dv = np.minimum(fv, 1.0 - fv)
    height = np.clip(np.minimum(du, dv) / g, 0.0, 1.0)
    height = height * height * (3.0 - 2.0 * height)  # smoothstep
    # per-tile colour jitter + fine noise
    ti, tj = (uu * tiles).astype(int), (vv * tiles).astype(int)
    jitter = rng.uniform(0.75, 1.0, size=(tiles, tiles))[tj, ti]
    noise = rng.normal(0.0, 0.03, size=(n, n))
    stone = np.array([0.62, 0.58, 0.50])
    grout = np.array([0.22, 0.21, 0.20])
    shade = np.clip(jitter + noise, 0.0, 1.0)[..., None]
    rgb = grout + (stone * shade - grout) * height[..., None]
    base = np.concatenate([np.clip(rgb, 0, 1), np.ones((n, n, 1))], axis=-1)
    # tangent-space normal from the height field: +x along +u, +y along +v (OpenGL / glTF
    # convention). Image rows go down while v goes up, hence the sign on the row gradient.
    depth = 0.01  # groove depth in texture units
    dh_du = np.gradient(height, axis=1) * n * depth
    dh_dv = -np.gradient(height, axis=0) * n * depth
    nrm = np.stack([-dh_du, -dh_dv, np.ones_like(height)], axis=-1)
    nrm /= np.linalg.norm(nrm, axis=-1, keepdims=True)
    normal = np.concatenate([nrm * 0.5 + 0.5, np.ones((n, n, 1))], axis=-1)
    return base, normal


def metal_rough_texture(rng):
    """Sphere: 8 horizontal bands alternating metal / dielectric, roughness ramp along u.
    R unused (1), G roughness, B metallic (glTF's metallicRoughness layout)."""
    n = TEX
    u = (np.arange(n) + 0.5) / n
    uu, vv = np.meshgrid(u, u)
    metallic = (np.floor(vv * 8) % 2 == 0).astype(float)
    roughness = 0.1 + 0.8 * (0.5 - 0.5 * np.cos(2 * np.pi * uu)) + rng.normal(0, 0.02, (n, n))
    rgba = np.stack([np.ones_like(uu), np.clip(roughness, 0, 1), metallic, np.ones_like(uu)],
                    axis=-1)
    return rgba


def cutout_texture(rng):
    """Cut-out panel: painted board with a 5 x 5 grid of round holes (alpha 0)."""
    n = TEX
    u = (np.arange(n) + 0.5) / n
    uu, vv = np.meshgrid(u, u)
    cu, cv = (uu * 5) % 1.0 - 0.5, (vv * 5) % 1.0 - 0.5
    hole = np.hypot(cu, cv) < 0.32
    stripes = ((uu + vv) * 10 % 1.0 < 0.5)
    rgb = np.where(stripes[..., None], [0.80, 0.30, 0.10], [0.90, 0.75, 0.20])
    rgb = np.clip(rgb + rng.normal(0, 0.02, (n, n, 1)), 0, 1)
    alpha = np.where(hole, 0.0, 1.0)[..., None]
    return np.concatenate([rgb, alpha], axis=-1)


# ---------------------------------------------------------------- materials

def principled_material(name):
    mat = bpy.data.materials.new(name)
    mat.use_nodes = True
    bsdf = mat.node_tree.nodes["Principled BSDF"]
    return mat, mat.node_tree, bsdf


def image_node(tree, img, x, y):
    node = tree.nodes.new("ShaderNodeTexImage")
    node.image = img
    node.location = (x, y)
    return node


def ground_material(base_img, normal_img):
    mat, tree, bsdf = principled_material("Tiles")
    tex = image_node(tree, base_img, -600, 300)
    tree.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    ntex = image_node(tree, normal_img, -600, -200)
    nmap = tree.nodes.new("ShaderNodeNormalMap")  # space TANGENT, active UV map
    nmap.location = (-300, -200)
    nmap.inputs["Strength"].default_value = 1.0
    tree.links.new(ntex.outputs["Color"], nmap.inputs["Color"])
    tree.links.new(nmap.outputs["Normal"], bsdf.inputs["Normal"])
    bsdf.inputs["Roughness"].default_value = 0.8
    bsdf.inputs["Metallic"].default_value = 0.0
    return mat


def sphere_material(mr_img):
    mat, tree, bsdf = principled_material("BandedMetal")
    bsdf.inputs["Base Color"].default_value = (0.85, 0.55, 0.35, 1.0)
    tex = image_node(tree, mr_img, -700, 0)
    sep = tree.nodes.new("ShaderNodeSeparateColor")
    sep.location = (-400, 0)
    tree.links.new(tex.outputs["Color"], sep.inputs["Color"])
    tree.links.new(sep.outputs["Green"], bsdf.inputs["Roughness"])
    tree.links.new(sep.outputs["Blue"], bsdf.inputs["Metallic"])
    return mat


def cube_material():
    mat, tree, bsdf = principled_material("BluePlastic")
    bsdf.inputs["Base Color"].default_value = (0.10, 0.25, 0.70, 1.0)
    bsdf.inputs["Roughness"].default_value = 0.35
    return mat


def cutout_material(img):
    mat, tree, bsdf = principled_material("CutOut")
    tex = image_node(tree, img, -500, 0)
    tree.links.new(tex.outputs["Color"], bsdf.inputs["Base Color"])
    tree.links.new(tex.outputs["Alpha"], bsdf.inputs["Alpha"])
    bsdf.inputs["Roughness"].default_value = 0.6
    mat.blend_method = "CLIP"
    mat.alpha_threshold = 0.5
    mat.shadow_method = "CLIP"
    mat.use_backface_culling = False  # -> doubleSided
    return mat


# ---------------------------------------------------------------- objects

def link(obj):
    bpy.context.scene.collection.objects.link(obj)
    return obj


def add_primitive(op, name, mat, **kw):
    op(**kw)
    obj = bpy.context.active_object
    obj.name = name
    obj.data.name = name
    obj.data.materials.append(mat)
    return obj


def add_uv_sphere(name, mat, segments, rings, radius, location):
    """Smooth UV sphere built from arrays (u around +z from +x, v = 1 at the north pole).

    Built here rather than with primitive_uv_sphere_add, whose vertex and face order changes
    from run to run, and with exact custom normals rather than Blender's smooth vertex normals,
    whose last bit does too: either changes the exported bytes."""
    verts = [(0.0, 0.0, radius)]
    for i in range(1, rings):
        theta = math.pi * i / rings
        for j in range(segments):
            phi = 2.0 * math.pi * j / segments
            verts.append((radius * math.sin(theta) * math.cos(phi),
                          radius * math.sin(theta) * math.sin(phi), radius * math.cos(theta)))
    verts.append((0.0, 0.0, -radius))
    south = len(verts) - 1

    def ring(i, j):  # vertex on ring i (1 .. rings-1), segment j (wraps)
        return 1 + (i - 1) * segments + j % segments

    faces, uvs = [], []
    for j in range(segments):
        u0, u1 = j / segments, (j + 1) / segments
        faces.append((0, ring(1, j), ring(1, j + 1)))
        uvs += [((u0 + u1) / 2, 1.0), (u0, 1.0 - 1 / rings), (u1, 1.0 - 1 / rings)]
        for i in range(1, rings - 1):
            v0, v1 = 1.0 - i / rings, 1.0 - (i + 1) / rings
            faces.append((ring(i, j), ring(i + 1, j), ring(i + 1, j + 1), ring(i, j + 1)))
            uvs += [(u0, v0), (u0, v1), (u1, v1), (u1, v0)]
        faces.append((ring(rings - 1, j), south, ring(rings - 1, j + 1)))
        uvs += [(u0, 1 / rings), ((u0 + u1) / 2, 0.0), (u1, 1 / rings)]

    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(verts, [], faces)
    layer = mesh.uv_layers.new(name="UVMap")
    layer.data.foreach_set("uv", np.array(uvs, dtype=np.float32).ravel())
    mesh.polygons.foreach_set("use_smooth", [True] * len(mesh.polygons))
    mesh.materials.append(mat)
    mesh.validate()
    mesh.update()
    # Exact normals as custom split normals: Blender's own smooth vertex normals are summed by
    # parallel threads, so their last bit changes from run to run.
    mesh.use_auto_smooth = True
    mesh.auto_smooth_angle = math.pi
    mesh.normals_split_custom_set_from_vertices([(x / radius, y / radius, z / radius)
                                                 for x, y, z in verts])
    mesh.update()
    obj = link(bpy.data.objects.new(name, mesh))
    obj.location = location
    return obj


def look_at(obj, target):
    direction = Vector(target) - obj.location
    obj.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler()


def build(out_dir, export_tangents=False):
    rng = np.random.default_rng(SEED)
    clear_scene()
    scene = bpy.context.scene

    base, normal = tile_textures(rng)
    tiles_img = make_image("tiles_basecolor", base)
    normal_img = make_image("tiles_normal", normal, non_color=True)
    mr_img = make_image("bands_metal_rough", metal_rough_texture(rng), non_color=True)
    cut_img = make_image("cutout_basecolor", cutout_texture(rng))

    # ground
    ground = add_primitive(bpy.ops.mesh.primitive_plane_add, "Ground",
                           ground_material(tiles_img, normal_img), size=20.0, location=(0, 0, 0))
    uv = ground.data.uv_layers.active.data  # repeat the 8 x 8 tile texture 2.5 times: 1 m tiles
    coords = np.empty(2 * len(uv), dtype=np.float32)
    uv.foreach_get("uv", coords)
    uv.foreach_set("uv", coords * 2.5)

    # textured sphere, centre of the scene
    add_uv_sphere("Sphere", sphere_material(mr_img), segments=64, rings=32, radius=1.0,
                  location=(0, 0.5, 1.0))

    # twelve linked duplicates of one cube mesh on an arc behind/around the sphere
    cube = add_primitive(bpy.ops.mesh.primitive_cube_add, "Block", cube_material(),
                         size=1.0, location=(0, 0, 0))
    blocks = [cube]
    for _ in range(11):
        blocks.append(link(cube.copy()))  # .copy() shares cube.data (Alt+D)
    for i, obj in enumerate(blocks):
        obj.name = f"Block.{i:02d}"
        a = math.radians(-150 + i * (120 / 11))  # arc from -150 deg to -30 deg: behind the sphere
        r = 3.6
        s = 0.35 + 0.25 * rng.random()
        h = s * (1.0 + 1.5 * rng.random())
        obj.location = (r * math.cos(a), 0.5 - r * math.sin(a), h / 2)
        obj.scale = (s, s, h)
        obj.rotation_euler = Euler((0.0, 0.0, a + rng.uniform(-0.4, 0.4)))

    # cut-out panel between the camera and the sphere, standing upright, facing the camera
    panel = add_primitive(bpy.ops.mesh.primitive_plane_add, "CutOutPanel", cutout_material(cut_img),
                          size=1.0, location=(1.2, -1.5, 0.95))
    panel.scale = (1.4, 1.4, 1.0)
    panel.rotation_euler = Euler((math.radians(90), 0.0, math.radians(20)))

    # lights
    sun_data = bpy.data.lights.new("Sun", type="SUN")
    sun_data.energy = 3.0  # W/m^2
    sun_data.angle = math.radians(0.5)
    sun = link(bpy.data.objects.new("Sun", sun_data))
    sun.location = (-6, 4, 5)
    elevation, azimuth = math.radians(25), math.radians(-30)  # light from the front right
    to_light = Vector((math.cos(elevation) * math.cos(azimuth),
                       math.cos(elevation) * math.sin(azimuth), math.sin(elevation)))
    sun.rotation_euler = (-to_light).to_track_quat("-Z", "Y").to_euler()

    point_data = bpy.data.lights.new("Fill", type="POINT")
    point_data.energy = 60.0  # W
    point_data.shadow_soft_size = 0.1
    point_data.color = (1.0, 0.85, 0.7)
    link(bpy.data.objects.new("Fill", point_data)).location = (3.0, -3.0, 3.0)

    # camera
    cam_data = bpy.data.cameras.new("Camera")
    cam_data.type = "PERSP"
    cam_data.sensor_fit = "AUTO"
    cam_data.angle = math.radians(40.0)
    cam_data.clip_start = 0.1
    cam_data.clip_end = 100.0
    cam = link(bpy.data.objects.new("Camera", cam_data))
    cam.location = (3.9, -8.4, 4.0)
    look_at(cam, (0.2, 0.9, 0.8))
    scene.camera = cam
    scene.render.resolution_x = 512
    scene.render.resolution_y = 512
    scene.render.resolution_percentage = 100

    # world: dim constant colour (not exported)
    world = bpy.data.worlds.new("World") if scene.world is None else scene.world
    scene.world = world
    world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (0.05, 0.06, 0.08, 1.0)
    bg.inputs["Strength"].default_value = 1.0

    bpy.context.view_layer.update()

    os.makedirs(out_dir, exist_ok=True)
    path = os.path.join(out_dir, "scene.gltf")
    bpy.ops.export_scene.gltf(
        filepath=path,
        export_format="GLTF_SEPARATE",
        export_lights=True,
        export_cameras=True,
        export_yup=True,
        export_tangents=export_tangents,
        export_image_format="AUTO",
        export_apply=False,
    )
    print(f"make_blender_scene: wrote {path}")


if __name__ == "__main__":
    build(*parse_args())
