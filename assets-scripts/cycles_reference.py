"""Render a glTF scene with Blender Cycles as an independent reference for target/release/render.

Run with Debian's `blender` package (3.4.x):

    blender --background --factory-startup --python assets-scripts/cycles_reference.py -- \\
        SCENE.gltf OUTPUT.exr [--spp N] [--resolution WxH] [--max-bounces B] [--seed S]
        [--filter-width PX] [--multiscatter] [--no-fixups] [--threads T]
    blender --background --factory-startup --python assets-scripts/cycles_reference.py -- --check-units

Writes OUTPUT.exr (linear scene-referred RGB, 32-bit float) and OUTPUT.png next to it (8-bit
sRGB through the 'Standard' view transform, look None, exposure 0: clamped, not tone-mapped).
Defaults: 256 spp, the resolution 512 x 512, max bounces 6, box pixel filter 1 px wide.
`--check-units` renders two tiny calibration scenes instead (see "Light units" below).

What it does
------------
1. Imports the glTF with Blender's own importer (`bpy.ops.import_scene.gltf`, Blender 3.4's
   io_scene_gltf2 3.4.50) into an empty scene, with `convert_lighting_mode='SPEC'` (the
   default: the specification's photometric units, 683 lm/W).
2. The world: a Background shader of colour `scenes[scene].extras.environment.color` (read
   from the glTF JSON by this script; the importer ignores extras) and strength 1. Our
   renderer treats that colour as constant radiance in W/(m^2 sr), and so does a Cycles
   Background of strength 1 (a camera ray that misses returns exactly that colour).
   An `environment.image` is not supported here (the script stops with a message).
3. The camera: the imported camera object named "camera", else the only camera object (the
   importer names objects after their nodes; Blender's exporter names a node after its Blender
   object, e.g. "Camera"). The importer sets `angle_y` = yfov and `sensor_fit` = VERTICAL, so
   the vertical field of view is kept for any aspect ratio, as in our renderer.
4. Cycles on the CPU, path tracing, `--spp` samples with adaptive sampling off, no denoising,
   no clamping (sample_clamp_direct = sample_clamp_indirect = 0), no glossy filter
   (blur_glossy = 0), light sampling threshold 0, caustics on, a fixed seed.
   Bounces: our `--max-depth 8` counts path segments as Mitsuba 3's max_depth does
   (1 = emitters seen directly, 2 = direct lighting); Cycles' max_bounces counts bounces
   after the first hit (0 = direct lighting only), so depth D is max_bounces D - 2 = 6,
   with diffuse/glossy/transmission bounces at the same limit; volume bounces 0. Transparent
   bounces (alpha pass-throughs) are counted separately in Cycles (limit 16); in our renderer
   alpha pass-throughs do not end a path either.
   Pixel filter: BOX of width 1 px (`--filter-width`, Cycles' minimum is 0.01 px). Our
   renderer jitters every sample uniformly inside its pixel and averages with equal weights,
   which is exactly Cycles' 1 px box; a smaller width would point-sample the pixel centres
   (aliased edges) and a Gaussian/Blackman-Harris filter would blur across pixels, so 1 px is
   the like-for-like choice. Cycles' default (Blackman-Harris 1.5 px) is NOT used.
5. Colour management: display sRGB, view transform 'Standard', look 'None', exposure 0,
   gamma 1. The EXR is linear whatever the view transform; the PNG is the clamped sRGB
   encoding of it.

What Blender 3.4's importer makes of the features the feature-showcase scene uses (checked by
reading io_scene_gltf2 3.4.50 and by the material dump this script prints):
- KHR_lights_punctual: sun.energy = lux / 683 (W/m^2, Cycles' sun strength is irradiance);
  point/spot energy = cd / 683 * 4 pi (W; Cycles' point light of power P has intensity
  P / (4 pi) W/sr). A 2049 lx sun becomes 3 W/m^2, a 1366 cd lamp 8 pi = 25.13 W (2 W/sr).
  Colour is copied. The script compares every imported light with the JSON and stops on a
  mismatch.
- KHR_materials_emissive_strength: read (Principled "Emission Strength" = emissiveStrength x
  the grey emissiveFactor; emissiveTexture -> "Emission" colour, sRGB).
- KHR_texture_transform: read (a Mapping node, converted to Blender's v-up UVs). Worked
  through, the importer's conversion gives u' = sx cos(r) u + sy sin(r) v + ox,
  v' = -sx sin(r) u + sy cos(r) v + oy: the rotation as corrected in KhronosGroup/glTF#1563
  (and as the extension's own JSON example, three.js, Babylon.js and cesium-native do it).
  The GLSL listing in the extension's README, read literally (GLSL is column-major), rotates
  the other way; our renderer follows that listing, so with rotation != 0 the two disagree.
  NOT fixed up: it is a finding (negating the rotation in a copy of the glTF makes the
  ground tiles of both renders coincide).
- texCoord 1: read (a UV Map node "UVMap.001").
- Samplers: REPEAT/REPEAT -> extension REPEAT, CLAMP/CLAMP -> EXTEND, mixed modes -> EXTEND
  plus per-axis Math WRAP (repeat) / PINGPONG (mirrored repeat) nodes; NEAREST/NEAREST ->
  interpolation 'Closest', otherwise 'Linear' (mipmaps ignored, as in our renderer).
- normalTexture: a Normal Map node (tangent space, strength = scale) on the UV map. Blender
  IGNORES the TANGENT attribute and always builds MikkTSpace tangents from the UVs itself, so
  Cycles is an independent check of both our TANGENT reading and our MikkTSpace.
- metallicRoughnessTexture: Separate RGB, G -> Roughness, B -> Metallic (non-colour data).
- alpha BLEND: base colour alpha x factor alpha -> Principled "Alpha" (Cycles: stochastic /
  transparent-BSDF mix, also for shadow rays: the alpha blend, as in our renderer).
- alpha MASK: the importer sets only EEVEE's blend_method = CLIP and alpha_threshold, which
  Cycles ignores; the raw alpha goes to "Alpha", i.e. Cycles would render a MASK as BLEND.
  FIXED UP below.
- KHR_materials_ior: sets the Principled "IOR" input, which in Blender 3.4's Principled v1
  only affects transmission; reflection F0 comes from "Specular" (F0 = 0.08 x Specular).
- KHR_materials_specular (no textures): Specular = lum(specularColorFactor) x f0(ior) / 0.08
  and a "Specular Tint" derived from the colour ratios; specularFactor is DROPPED (so the
  cylinder's F0 would be 0.075 instead of the specified ~0.052). FIXED UP below.
- doubleSided: only `use_backface_culling` (EEVEE); Cycles shades both sides of everything
  (our renderer: a single-sided surface is black from behind). Not fixed up: no single-sided
  surface of the feature-showcase scene is seen from behind.
- The Principled node's distribution is left at the node default (GGX, single scattering
  in 3.4, printed below); `--multiscatter` switches to Multiscatter GGX.

Fix-ups applied by hand (all printed; `--no-fixups` renders the importer's result as is):
- Lights: point `shadow_soft_size` (Blender default 0.25 m radius) and sun `angle` (default
  0.526 deg) set to 0: glTF punctual lights are points and an infinitely distant sun.
- alpha MASK: Principled "Alpha" = 1 - (alpha < alphaCutoff), a hard cut-out (a Math
  LESS_THAN and a SUBTRACT node after the importer's alpha chain).
- KHR_materials_ior / KHR_materials_specular: Specular = Y(f0) / 0.08 and Specular Tint 0,
  with f0 = min(((ior - 1)/(ior + 1))^2 x specularColorFactor, 1) x specularFactor (the
  extension's definition; Y = Rec. 709 luminance). What stays different: Blender's F0 is
  grey (the specular colour's tint is lost), its Fresnel goes to 1 at grazing angles (the
  extension's f90 = specularFactor), and its diffuse layer is not weighted by 1 - F.
- 8-bit sRGB textures (base colour, emissive): Cycles stores them as bytes and converts
  sRGB to linear AFTER bilinear interpolation (svm_image_texture's
  NODE_IMAGE_COMPRESS_AS_SRGB path), i.e. it filters sRGB-encoded values, while glTF (and
  our renderer) decode to linear first. Measured on this scene at 256 x 256: the emissive
  sign's minified lettering comes out 10 % darker that way, the brick slab 1-2 %, everything
  else within 0.3 %. Each such image is replaced by a float copy of its decoded linear
  values (premultiplied by alpha, as Blender's float buffers are), colour space Linear.
- Single-sided emission: glTF (and our renderer) emits from the front face only; Cycles'
  emission is two-sided. For materials that are not doubleSided, Emission Strength is
  multiplied by 1 - Backfacing (Geometry node), so the sign's back does not light the
  ground behind it.

Known model differences that are NOT fixed (they are what the comparison measures):
- Blender 3.4's Principled v1 diffuse is Disney's (retro-reflective with roughness, fd90 =
  0.5 + 2 roughness cos^2 theta_d) and is simply added under the specular layer; ours is
  Lambertian weighted by T(mu_o) T(mu_i) (energy conserving, see
  renderer/src/bsdf/metallic_roughness.rs), so Cycles' rough dielectrics come out a few per
  cent brighter, more at grazing angles.
- Principled's dielectric Fresnel interpolates F0 -> 1 with the true dielectric Fresnel of
  the equivalent ior, ours is Schlick's; metals use the base colour as F0 in both.
- Normal maps: Cycles' Normal Map node bends the mapped normal back towards the geometric
  normal wherever the view direction's mirror image would fall below the surface
  (ensure_valid_reflection); our renderer uses the mapped normal as is, and its BSDFs are
  zero where the view direction lies below the shading normal's hemisphere. With the ground's
  egg-crate bumps (tilts up to 23 degrees) the two differ near grazing view angles.
- Pixel filter: equal (1 px box); texture filtering: both bilinear without mipmaps, but
  Blender decodes the JPEG with its own libjpeg (sub-LSB differences).

Light units (`--check-units`): renders, with max bounces 0 and a black world, a diffuse
plane (albedo 0.5) under (a) a sun of strength 3 W/m^2 at normal incidence and (b) a point
light of 4 pi W (1 W/sr) 1 m above it, and compares the plane's radiance with
albedo x E / pi (0.4775 and 0.1592). Blender 3.4.1: both ratios 1.0000.

NumPy: Blender 3.4's importer still uses `np.bool`, which NumPy 1.24 removed (Debian's
python3-numpy is newer, so the import fails with AttributeError); the script sets
`numpy.bool = bool` before importing.

Expected noise in Blender's log: "ERROR: Draco mesh compression is not available" (Debian
ships no Draco; unused).
"""

import json
import math
import os
import sys

import bpy
from mathutils import Vector

LUMENS_PER_WATT = 683.0


def usage(message=None):
    if message:
        print("cycles_reference.py: " + message, file=sys.stderr)
    sys.exit("usage: blender --background --factory-startup --python "
             "assets-scripts/cycles_reference.py -- SCENE.gltf OUTPUT.exr [--spp N] "
             "[--resolution WxH] [--max-bounces B] [--seed S] [--filter-width PX] "
             "[--multiscatter] [--no-fixups] [--threads T] | --check-units")


def parse_args():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    opts = {"spp": 256, "resolution": (512, 512), "max_bounces": 6, "seed": 0,
            "filter_width": 1.0, "multiscatter": False, "fixups": True, "threads": 0,
            "check_units": False}
    positional = []
    i = 0
    while i < len(argv):
        a = argv[i]

        def value():
            if i + 1 >= len(argv):
                usage(a + " needs a value")
            return argv[i + 1]

        if a == "--spp":
            opts["spp"] = int(value()); i += 2
        elif a == "--resolution":
            try:
                w, h = value().lower().split("x")
                opts["resolution"] = (int(w), int(h))
            except ValueError:
                usage("--resolution takes WIDTHxHEIGHT")
            i += 2
        elif a == "--max-bounces":
            opts["max_bounces"] = int(value()); i += 2
        elif a == "--seed":
            opts["seed"] = int(value()); i += 2
        elif a == "--filter-width":
            opts["filter_width"] = float(value()); i += 2
        elif a == "--threads":
            opts["threads"] = int(value()); i += 2
        elif a == "--multiscatter":
            opts["multiscatter"] = True; i += 1
        elif a == "--no-fixups":
            opts["fixups"] = False; i += 1
        elif a == "--check-units":
            opts["check_units"] = True; i += 1
        elif a.startswith("-"):
            usage("unknown option " + a)
        else:
            positional.append(a); i += 1
    if opts["check_units"]:
        if positional:
            usage("--check-units takes no files")
        return opts
    if len(positional) != 2:
        usage()
    opts["scene"], opts["output"] = (os.path.abspath(p) for p in positional)
    if not opts["output"].lower().endswith(".exr"):
        usage("OUTPUT must end in .exr")
    return opts


# ----------------------------------------------------------------------------- scene set-up


def empty_scene():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    return bpy.context.scene


def setup_cycles(scene, opts, width, height):
    scene.render.engine = "CYCLES"
    c = scene.cycles
    c.device = "CPU"
    c.feature_set = "SUPPORTED"
    c.progressive = "PATH"
    c.samples = opts["spp"]
    c.use_adaptive_sampling = False
    c.use_denoising = False
    c.sample_clamp_direct = 0.0
    c.sample_clamp_indirect = 0.0
    c.blur_glossy = 0.0
    c.caustics_reflective = True
    c.caustics_refractive = True
    c.light_sampling_threshold = 0.0
    c.seed = opts["seed"]
    c.use_animated_seed = False
    b = opts["max_bounces"]
    c.max_bounces = b
    c.diffuse_bounces = b
    c.glossy_bounces = b
    c.transmission_bounces = b
    c.volume_bounces = 0
    c.transparent_max_bounces = 16
    c.pixel_filter_type = "BOX"
    c.filter_width = opts["filter_width"]
    scene.render.film_transparent = False
    scene.render.resolution_x = width
    scene.render.resolution_y = height
    scene.render.resolution_percentage = 100
    scene.render.pixel_aspect_x = scene.render.pixel_aspect_y = 1.0
    scene.render.use_border = False
    if opts["threads"] > 0:
        scene.render.threads_mode = "FIXED"
        scene.render.threads = opts["threads"]
    scene.display_settings.display_device = "sRGB"
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    scene.view_settings.exposure = 0.0
    scene.view_settings.gamma = 1.0
    scene.view_settings.use_curve_mapping = False


def set_world_color(scene, color):
    world = bpy.data.worlds.new("environment")
    world.use_nodes = True
    bg = world.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (color[0], color[1], color[2], 1.0)
    bg.inputs["Strength"].default_value = 1.0
    scene.world = world


def render_to(scene, exr_path):
    """Renders once and writes EXR (linear float) and PNG (view-transformed) next to it."""
    bpy.ops.render.render(write_still=False)
    result = bpy.data.images["Render Result"]
    s = scene.render.image_settings
    s.file_format = "OPEN_EXR"
    s.color_mode = "RGB"
    s.color_depth = "32"
    s.exr_codec = "ZIP"
    result.save_render(exr_path, scene=scene)
    png_path = os.path.splitext(exr_path)[0] + ".png"
    s.file_format = "PNG"
    s.color_mode = "RGB"
    s.color_depth = "8"
    s.compression = 90
    result.save_render(png_path, scene=scene)
    return png_path


# ------------------------------------------------------------------------------ inspection


def upstream(socket, depth=0, seen=None):
    """A one-line description of what feeds `socket` (node types and key settings)."""
    if not socket.is_linked:
        v = socket.default_value
        try:
            v = tuple(round(x, 4) for x in v)
        except TypeError:
            v = round(v, 4) if isinstance(v, float) else v
        return repr(v)
    link = socket.links[0]
    node = link.from_node
    desc = node.bl_idname.replace("ShaderNode", "")
    extra = []
    if node.bl_idname == "ShaderNodeTexImage":
        img = node.image
        extra.append("%s[%s] %s %s %s" % (
            img.name if img else None, link.from_socket.name,
            img.colorspace_settings.name if img else "", node.interpolation, node.extension))
    elif node.bl_idname == "ShaderNodeMath":
        extra.append(node.operation + " " + ",".join(
            str(round(i.default_value, 4)) for i in node.inputs if not i.is_linked and i.enabled))
    elif node.bl_idname == "ShaderNodeMapping":
        extra.append("loc %s rot %s scale %s" % tuple(
            tuple(round(x, 4) for x in node.inputs[k].default_value)
            for k in ("Location", "Rotation", "Scale")))
    elif node.bl_idname == "ShaderNodeUVMap":
        extra.append(node.uv_map)
    elif node.bl_idname == "ShaderNodeNormalMap":
        extra.append("%s uv=%r strength=%s" % (node.space, node.uv_map,
                                               round(node.inputs["Strength"].default_value, 4)))
    elif node.bl_idname == "ShaderNodeMix":
        extra.append(node.blend_type)
    if link.from_socket.name not in ("Color", "Value", "Vector", "Result", "Normal"):
        extra.append("." + link.from_socket.name)
    s = desc + ("(" + " ".join(extra) + ")" if extra else "")
    inputs = [i for i in node.inputs if i.is_linked]
    if inputs and depth < 8:
        s += " <- " + " + ".join(upstream(i, depth + 1) for i in inputs)
    return s


PRINCIPLED_INPUTS = ("Base Color", "Metallic", "Roughness", "Specular", "Specular Tint", "IOR",
                     "Emission", "Emission Strength", "Alpha", "Normal")


def principled(mat):
    if not mat.use_nodes:
        return None
    for n in mat.node_tree.nodes:
        if n.bl_idname == "ShaderNodeBsdfPrincipled":
            return n
    return None


def print_materials(label):
    print("\n== materials (%s) ==" % label)
    for mat in sorted(bpy.data.materials, key=lambda m: m.name):
        p = principled(mat)
        print("material %r: blend_method %s alpha_threshold %.3f backface_culling %s" % (
            mat.name, mat.blend_method, mat.alpha_threshold, mat.use_backface_culling))
        if p is None:
            print("    (no Principled BSDF)")
            continue
        print("    distribution %s" % p.distribution)
        for name in PRINCIPLED_INPUTS:
            print("    %-17s %s" % (name, upstream(p.inputs[name])))


def print_lights(label):
    print("\n== lights (%s) ==" % label)
    for obj in bpy.data.objects:
        if obj.type != "LIGHT":
            continue
        light = obj.data
        if light.type == "SUN":
            direction = (obj.matrix_world.to_3x3() @ Vector((0.0, 0.0, -1.0))).normalized()
            where = "angle %.5f rad, travelling along %s (Blender z-up)" % (
                light.angle, tuple(round(x, 4) for x in direction))
        else:
            where = "radius %.4f m, at %s (Blender z-up)" % (
                light.shadow_soft_size, tuple(round(x, 4) for x in obj.matrix_world.translation))
        print("light %r: %s energy %.6f %s, colour %s, %s" % (
            obj.name, light.type, light.energy, "W/m^2" if light.type == "SUN" else "W",
            tuple(round(c, 4) for c in light.color), where))


# ------------------------------------------------------------------------------- checks


def check_lights(gltf):
    """The imported lights against the glTF JSON in the spec's photometric units."""
    lights = gltf.get("extensions", {}).get("KHR_lights_punctual", {}).get("lights", [])
    ok = True
    for i, pl in enumerate(lights):
        name = pl.get("name")
        data = bpy.data.lights.get(name) if name else None
        if data is None:
            print("light %d (%r): not found by name in Blender, not checked" % (i, name))
            continue
        intensity = pl.get("intensity", 1.0)
        if pl["type"] == "directional":
            expected, unit, radiometric = intensity / LUMENS_PER_WATT, "W/m^2", "irradiance"
        else:
            expected, unit, radiometric = intensity / LUMENS_PER_WATT * 4 * math.pi, "W", "power"
        good = abs(data.energy - expected) <= 1e-4 * max(1.0, expected)
        ok &= good
        print("light %r: glTF %s %.4g %s -> Blender %.6f %s, expected %.6f (%s; %s)" % (
            name, pl["type"], intensity, "lx" if pl["type"] == "directional" else "cd",
            data.energy, unit, expected, radiometric, "ok" if good else "MISMATCH"))
        if pl["type"] != "directional":
            print("    = %.6f W/sr radiant intensity" % (data.energy / (4 * math.pi)))
        col = tuple(pl.get("color", [1, 1, 1]))
        if max(abs(a - b) for a, b in zip(col, data.color)) > 1e-6:
            ok = False
            print("    colour MISMATCH: %s vs %s" % (col, tuple(data.color)))
    if not ok:
        sys.exit("cycles_reference.py: the imported lights do not match the glTF")


# ------------------------------------------------------------------------------- fix-ups


def luminance(rgb):
    return 0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]


def fix_lights():
    for l in bpy.data.lights:
        if l.type == "SUN":
            print("fix-up: sun %r angle %.5f -> 0" % (l.name, l.angle))
            l.angle = 0.0
        else:
            print("fix-up: %s %r radius %.4f -> 0" % (l.type.lower(), l.name, l.shadow_soft_size))
            l.shadow_soft_size = 0.0


def fix_alpha_mask(mat, cutoff):
    p = principled(mat)
    tree = mat.node_tree
    alpha = p.inputs["Alpha"]
    if not alpha.is_linked:
        v = alpha.default_value
        alpha.default_value = 0.0 if v < cutoff else 1.0
        print("fix-up: %r alpha MASK: constant alpha %.3f -> %.1f" % (mat.name, v,
                                                                      alpha.default_value))
        return
    source = alpha.links[0].from_socket
    less = tree.nodes.new("ShaderNodeMath")
    less.operation = "LESS_THAN"
    less.inputs[1].default_value = cutoff
    tree.links.new(source, less.inputs[0])
    one_minus = tree.nodes.new("ShaderNodeMath")
    one_minus.operation = "SUBTRACT"
    one_minus.inputs[0].default_value = 1.0
    tree.links.new(less.outputs[0], one_minus.inputs[1])
    tree.links.new(one_minus.outputs[0], alpha)
    print("fix-up: %r alpha MASK: Alpha = 1 - (alpha < %.3f) (importer fed raw alpha)" % (
        mat.name, cutoff))


def fix_specular(mat, ext):
    p = principled(mat)
    ior = ext.get("KHR_materials_ior", {}).get("ior", 1.5)
    spec = ext.get("KHR_materials_specular", {})
    if "specularTexture" in spec or "specularColorTexture" in spec:
        print("warning: %r: KHR_materials_specular textures are not mapped" % mat.name)
    factor = spec.get("specularFactor", 1.0)
    color = spec.get("specularColorFactor", [1.0, 1.0, 1.0])
    r = ((ior - 1) / (ior + 1)) ** 2
    f0 = [min(r * c, 1.0) * factor for c in color]
    old = (p.inputs["Specular"].default_value, p.inputs["Specular Tint"].default_value)
    if p.inputs["Specular"].is_linked or p.inputs["Specular Tint"].is_linked:
        print("warning: %r: Specular is textured by the importer; left as is" % mat.name)
        return
    p.inputs["Specular"].default_value = luminance(f0) / 0.08
    p.inputs["Specular Tint"].default_value = 0.0
    print("fix-up: %r ior %.3g specular %.3g colour %s: f0 = (%.4f, %.4f, %.4f), "
          "Specular %.4f -> %.4f (F0 %.4f -> %.4f), Specular Tint %.4f -> 0" % (
              mat.name, ior, factor, color, *f0, old[0], p.inputs["Specular"].default_value,
              0.08 * old[0], luminance(f0), old[1]))


def fix_one_sided_emission(mat):
    p = principled(mat)
    tree = mat.node_tree
    strength = p.inputs["Emission Strength"]
    geometry = tree.nodes.new("ShaderNodeNewGeometry")
    front = tree.nodes.new("ShaderNodeMath")
    front.operation = "SUBTRACT"
    front.inputs[0].default_value = 1.0
    tree.links.new(geometry.outputs["Backfacing"], front.inputs[1])
    mult = tree.nodes.new("ShaderNodeMath")
    mult.operation = "MULTIPLY"
    if strength.is_linked:
        tree.links.new(strength.links[0].from_socket, mult.inputs[0])
    else:
        mult.inputs[0].default_value = strength.default_value
    tree.links.new(front.outputs[0], mult.inputs[1])
    tree.links.new(mult.outputs[0], strength)
    print("fix-up: %r single-sided emission: Emission Strength x (1 - Backfacing)" % mat.name)


def linearize_srgb_images():
    """Cycles keeps 8-bit sRGB images as bytes and decodes sRGB AFTER bilinear filtering
    (svm_image_texture: interpolate, then color_srgb_to_linear), i.e. it filters sRGB-encoded
    values; glTF and our renderer decode to linear first and filter linear values. Replace
    every 8-bit sRGB image by a float copy holding the decoded linear values (premultiplied
    by alpha: Blender's float buffers are premultiplied, and Cycles un-premultiplies where
    the Alpha output is used), colour space Linear, so Cycles filters in linear space too."""
    import numpy as np
    converted = {}
    for img in list(bpy.data.images):
        if img.colorspace_settings.name != "sRGB" or img.is_float or img.size[0] == 0:
            continue
        w, h = img.size
        px = np.empty(w * h * 4, np.float32)
        img.pixels.foreach_get(px)  # byte images: the stored sRGB-encoded values / 255
        px = px.reshape(-1, 4)
        rgb = px[:, :3]
        px[:, :3] = np.where(rgb <= 0.04045, rgb / 12.92,
                             ((rgb + 0.055) / 1.055) ** 2.4) * px[:, 3:4]
        new = bpy.data.images.new(img.name + "-linear", w, h, alpha=True, float_buffer=True)
        new.colorspace_settings.name = "Linear"
        new.alpha_mode = "PREMUL"
        new.pixels.foreach_set(px.ravel())
        new.pack()
        converted[img.name] = new
    for mat in bpy.data.materials:
        if not mat.use_nodes:
            continue
        for node in mat.node_tree.nodes:
            if node.bl_idname == "ShaderNodeTexImage" and node.image and \
                    node.image.name in converted:
                node.image = converted[node.image.name]
    for name in sorted(converted):
        print("fix-up: image %r (8-bit sRGB) -> linear float %r (filtered in linear space)" % (
            name, converted[name].name))


def apply_fixups(gltf, multiscatter):
    fix_lights()
    linearize_srgb_images()
    by_name = {m.get("name"): m for m in gltf.get("materials", [])}
    for mat in bpy.data.materials:
        p = principled(mat)
        gm = by_name.get(mat.name)
        if p is None or gm is None:
            continue
        p.distribution = "MULTI_GGX" if multiscatter else "GGX"
        if gm.get("alphaMode") == "MASK":
            fix_alpha_mask(mat, gm.get("alphaCutoff", 0.5))
        ext = gm.get("extensions", {})
        if "KHR_materials_ior" in ext or "KHR_materials_specular" in ext:
            fix_specular(mat, ext)
        emissive = gm.get("emissiveFactor", [0, 0, 0])
        if any(e > 0 for e in emissive) and not gm.get("doubleSided", False):
            fix_one_sided_emission(mat)


# ----------------------------------------------------------------------------- main modes


def numpy_bool_shim():
    """Blender 3.4's importer uses `np.bool` (gltf2_blender_mesh.py, set_poly_smoothing), an
    alias NumPy 1.24 removed; Debian's python3-numpy is newer. Restore it as the builtin."""
    import numpy as np
    if "bool" not in np.__dict__:
        np.bool = bool


def render_scene(opts):
    with open(opts["scene"]) as f:
        gltf = json.load(f)
    scene_index = gltf.get("scene", 0)
    extras = (gltf.get("scenes", [{}])[scene_index].get("extras") or gltf.get("asset", {})
              .get("extras") or {})
    env = extras.get("environment", {})
    if "image" in env:
        sys.exit("cycles_reference.py: environment images are not supported (only 'color')")
    env_color = [c * env.get("strength", 1.0) for c in env.get("color", [0.0, 0.0, 0.0])]

    scene = empty_scene()
    numpy_bool_shim()
    result = bpy.ops.import_scene.gltf(filepath=opts["scene"], convert_lighting_mode="SPEC")
    if "FINISHED" not in result:
        sys.exit("cycles_reference.py: the glTF import failed: %s" % result)
    scene = bpy.context.scene
    width, height = opts["resolution"]
    setup_cycles(scene, opts, width, height)
    set_world_color(scene, env_color)
    print("\nworld: Background colour %s strength 1" % (env_color,))

    cam = bpy.data.objects.get("camera")
    if cam is None or cam.type != "CAMERA":
        cameras = [o for o in bpy.data.objects if o.type == "CAMERA"]
        if len(cameras) != 1:
            sys.exit("cycles_reference.py: no camera object named 'camera' (nor a single camera) "
                     "after the import")
        cam = cameras[0]
    scene.camera = cam
    print("camera %r: angle_y %.4f deg, sensor_fit %s, clip %.3g..%.3g, at %s" % (
        cam.name, math.degrees(cam.data.angle_y), cam.data.sensor_fit, cam.data.clip_start,
        cam.data.clip_end, tuple(round(x, 4) for x in cam.matrix_world.translation)))

    print_lights("as imported")
    check_lights(gltf)
    print_materials("as imported")
    if opts["fixups"]:
        print("\n== fix-ups ==")
        apply_fixups(gltf, opts["multiscatter"])
        print_lights("rendered")
        print_materials("rendered")
    elif opts["multiscatter"]:
        for mat in bpy.data.materials:
            if principled(mat):
                principled(mat).distribution = "MULTI_GGX"

    print("\nrendering %dx%d, %d spp, max bounces %d, box filter %.2f px ..." % (
        width, height, opts["spp"], opts["max_bounces"], opts["filter_width"]))
    os.makedirs(os.path.dirname(opts["output"]) or ".", exist_ok=True)
    png = render_to(scene, opts["output"])
    print("wrote %s and %s" % (opts["output"], png))


def check_units(opts):
    """Diffuse plane (albedo 0.5) under a 3 W/m^2 sun and a 1 W/sr point light."""
    import tempfile
    results = []
    for case in ("sun", "point"):
        scene = empty_scene()
        setup_cycles(scene, dict(opts, spp=16, max_bounces=0), 8, 8)
        set_world_color(scene, [0.0, 0.0, 0.0])
        bpy.ops.mesh.primitive_plane_add(size=20.0)
        plane = bpy.context.active_object
        mat = bpy.data.materials.new("white")
        mat.use_nodes = True
        nodes = mat.node_tree.nodes
        nodes.remove(nodes["Principled BSDF"])
        diffuse = nodes.new("ShaderNodeBsdfDiffuse")
        diffuse.inputs["Color"].default_value = (0.5, 0.5, 0.5, 1.0)
        diffuse.inputs["Roughness"].default_value = 0.0
        mat.node_tree.links.new(diffuse.outputs[0], nodes["Material Output"].inputs["Surface"])
        plane.data.materials.append(mat)
        cam_data = bpy.data.cameras.new("cam")
        cam_data.type = "ORTHO"
        cam_data.ortho_scale = 0.01
        cam = bpy.data.objects.new("cam", cam_data)
        cam.location = (0.0, 0.0, 0.5)
        scene.collection.objects.link(cam)
        scene.camera = cam
        if case == "sun":
            light = bpy.data.lights.new("sun", "SUN")
            light.energy, light.angle, expected = 3.0, 0.0, 0.5 * 3.0 / math.pi
            z = 5.0
        else:
            light = bpy.data.lights.new("point", "POINT")
            light.energy, light.shadow_soft_size = 4 * math.pi, 0.0
            expected = 0.5 * 1.0 / math.pi  # I = 1 W/sr at 1 m: E = 1 W/m^2
            z = 1.0
        obj = bpy.data.objects.new(case, light)
        obj.location = (0.0, 0.0, z)
        scene.collection.objects.link(obj)
        path = os.path.join(tempfile.mkdtemp(), case + ".exr")
        render_to(scene, path)
        img = bpy.data.images.load(path)
        px = list(img.pixels)
        n = img.size[0] * img.size[1]
        mean = sum(px[4 * i] for i in range(n)) / n
        results.append((case, mean, expected))
    print("\n== light units (Cycles %s) ==" % bpy.app.version_string)
    for case, mean, expected in results:
        print("%-5s: plane radiance %.5f, albedo x E / pi = %.5f, ratio %.4f" % (
            case, mean, expected, mean / expected))


def main():
    opts = parse_args()
    if opts["check_units"]:
        check_units(opts)
    else:
        render_scene(opts)


if __name__ == "__main__":
    main()
