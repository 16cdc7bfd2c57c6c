# SPDX-License-Identifier: MIT
"""The glTF that `render` reads: Blender's own exporter plus hooks that write the bindings.

`BindingsExtension` is handed to Blender's glTF exporter (as `glTF2ExportUserExtension`, the
name it looks up in enabled add-ons), so an export by hand carries the bindings too:
- a material's `neural_brdf` settings become the extras `render` reads (README, "Neural
  materials" and "Materials that vary across a surface"): `{"neural": "CODE"}`,
  `{"brdf": "merl:PATH"}`, `{"neural": {"mix": [...], "weights": TEXTURE}}`,
  `{"neural": {"blend": [A, B], "t": TEXTURE, "channel": C}}`, `{"neural": {"code": A,
  "tint": TEXTURE}}`; images become glTF textures embedded as `data:` URIs;
- a material without a code whose surface is a Diffuse BSDF of constant colour, which the
  exporter does not understand, becomes `{"bsdf": "diffuse"}` (Lambertian) with that colour
  as base colour (Blender's Diffuse BSDF at roughness 0 is Lambertian too);
- the scene's extras get `{"environment": {"color": C x strength}}` from a world whose
  surface is a Background of constant colour (or a world without nodes), unless the scene
  has an `environment` custom property of its own.
The add-on's own property groups are taken out of the extras.

Exporter hooks swallow exceptions, so `check_bindings` validates the bindings first: the
engine calls it before exporting and reports its errors.
"""

import base64
import os
import threading
import time

import bpy

from .runner import Cancelled, RenderError

# A texture in the extras before the glTF's image list is known.
_IMAGE_KEY = "__neural_brdf_image__"


def _binding_path(code):
    """A written binding with its path made absolute (`render` reads paths relative to the
    glTF file, which lives elsewhere); a latent name unchanged."""
    kind, sep, rest = code.partition(":")
    if sep and kind in ("merl", "nbrdf") and rest:
        return f"{kind}:{bpy.path.abspath(rest)}"
    return code


def _texture(binding, field, what, material):
    name = getattr(binding, field).strip()
    if not name:
        raise RenderError(f"material '{material.name}': {what} needs an image (Material Properties > Neural BRDF)")
    image = bpy.data.images.get(name)
    if image is None:
        raise RenderError(f"material '{material.name}': {what}: no image called '{name}'")
    image_bytes(image, f"{what} of material '{material.name}'")  # checked now, read at export
    return {_IMAGE_KEY: image.name_full, "texCoord": 0}


def image_bytes(image, what):
    """The PNG or JPEG bytes of a Blender image (packed, or its file) and their MIME type."""
    if image.packed_file is not None:
        data = bytes(image.packed_file.data)
        source = "its packed file"
    elif image.source == 'FILE' and image.filepath:
        path = bpy.path.abspath(image.filepath, library=image.library)
        try:
            with open(path, "rb") as f:
                data = f.read()
        except OSError as e:
            raise RenderError(f"image '{image.name}' ({what}): {path}: {e.strerror}") from None
        source = path
    else:
        raise RenderError(f"image '{image.name}' ({what}) is neither saved nor packed: save it as PNG")
    if data.startswith(b"\x89PNG\r\n\x1a\n"):
        return data, "image/png"
    if data.startswith(b"\xff\xd8"):
        return data, "image/jpeg"
    raise RenderError(f"image '{image.name}' ({what}): {source} is not a PNG or JPEG file")


def _active_surface(material):
    """The node linked to the Surface of the material's active output, or None."""
    if not material.use_nodes or material.node_tree is None:
        return None
    outputs = [n for n in material.node_tree.nodes if n.bl_idname == "ShaderNodeOutputMaterial"]
    active = [n for n in outputs if n.is_active_output] or outputs
    if not active or not active[0].inputs["Surface"].is_linked:
        return None
    return active[0].inputs["Surface"].links[0].from_node


def diffuse_colour(material):
    """The colour of a material whose surface is a Diffuse BSDF of constant colour, else None."""
    node = _active_surface(material)
    if node is None or node.bl_idname != "ShaderNodeBsdfDiffuse" or node.inputs["Color"].is_linked:
        return None
    return list(node.inputs["Color"].default_value)[:3]


def binding_extras(material):
    """The extras entries `render` reads for a material's binding (empty: none), textures as
    placeholders. Raises RenderError for an incomplete binding."""
    b = material.neural_brdf
    codes = [_binding_path(c) for c in b.codes()]
    if b.mode == 'CODE' and not codes:
        return {"bsdf": "diffuse"} if diffuse_colour(material) is not None else {}
    tint = _texture(b, "tint", "the tint", material) if b.tint.strip() else None
    if b.mode == 'CODE':
        if tint is not None:
            return {"neural": {"code": codes[0], "tint": tint}}
        if ":" in codes[0]:
            return {"brdf": codes[0]}
        return {"neural": codes[0]}
    if b.mode == 'MIX':
        if not codes:
            raise RenderError(f"material '{material.name}': a mix needs at least one code")
        neural = {"mix": codes, "weights": _texture(b, "weights", "the mix weights", material)}
    else:
        if len(codes) != 2:
            raise RenderError(f"material '{material.name}': a blend needs Code and Code B")
        if any(":" in c for c in codes):
            raise RenderError(f"material '{material.name}': only latent codes blend (a table or network has no latent space)")
        neural = {"blend": codes, "t": _texture(b, "weights", "the blend's t", material), "channel": b.channel}
    if tint is not None:
        neural["tint"] = tint
    return {"neural": neural}


def scene_materials(depsgraph):
    """The original materials the depsgraph evaluates."""
    return [i.original for i in depsgraph.ids if isinstance(i, bpy.types.Material)]


def check_bindings(depsgraph):
    """Raises RenderError for the first incomplete binding of the rendered materials."""
    for material in scene_materials(depsgraph):
        binding_extras(material)


def world_environment(world):
    """`{"color": [r, g, b]}` of a world of constant colour, None for another world (and a
    reason), or black for none."""
    if world is None:
        return {"color": [0.0, 0.0, 0.0]}, None
    if not world.use_nodes or world.node_tree is None:
        return {"color": list(world.color)[:3]}, None
    outputs = [n for n in world.node_tree.nodes if n.bl_idname == "ShaderNodeOutputWorld"]
    active = [n for n in outputs if n.is_active_output] or outputs
    if not active or not active[0].inputs["Surface"].is_linked:
        return {"color": [0.0, 0.0, 0.0]}, None
    node = active[0].inputs["Surface"].links[0].from_node
    if node.bl_idname != "ShaderNodeBackground" or node.inputs["Color"].is_linked or node.inputs["Strength"].is_linked:
        return None, (
            f"world '{world.name}': only a Background of constant colour is exported (the sky renders black; "
            "a scene custom property 'environment' sets an image, see the README)"
        )
    strength = node.inputs["Strength"].default_value
    return {"color": [c * strength for c in list(node.inputs["Color"].default_value)[:3]]}, None


class BindingsExtension:
    """Hooks of Blender's glTF exporter (see the module documentation)."""

    def __init__(self):
        self.images = {}

    def gather_material_hook(self, gltf2_material, blender_material, export_settings):
        material = getattr(blender_material, "original", blender_material)
        extras = dict(gltf2_material.extras or {})
        extras.pop("neural_brdf", None)
        try:
            entries = binding_extras(material)
        except RenderError as e:
            print(f"Neural BRDF: {e}: not exported")
            entries = {}
        if entries.get("bsdf") == "diffuse":
            self._set_base_colour(gltf2_material, diffuse_colour(material))
        for key in ("neural", "brdf", "bsdf"):
            extras.pop(key, None)
        extras.update(entries)
        gltf2_material.extras = extras or None

    @staticmethod
    def _set_base_colour(gltf2_material, colour):
        from io_scene_gltf2.io.com import gltf2_io

        pbr = gltf2_material.pbr_metallic_roughness
        if pbr is None:
            pbr = gltf2_io.MaterialPBRMetallicRoughness(
                base_color_factor=None,
                base_color_texture=None,
                extensions=None,
                extras=None,
                metallic_factor=None,
                metallic_roughness_texture=None,
                roughness_factor=None,
            )
            gltf2_material.pbr_metallic_roughness = pbr
        pbr.base_color_factor = list(colour) + [1.0]
        pbr.base_color_texture = None
        pbr.metallic_factor = 0.0

    def gather_scene_hook(self, gltf2_scene, blender_scene, export_settings):
        extras = dict(gltf2_scene.extras or {})
        extras.pop("neural_brdf", None)
        if "environment" not in extras:
            environment, _ = world_environment(blender_scene.world)
            if environment is not None:
                extras["environment"] = environment
        gltf2_scene.extras = extras or None

    def gather_gltf_extensions_hook(self, gltf2_plan, export_settings):
        """Turns the image placeholders of the materials' extras into embedded textures."""
        from io_scene_gltf2.io.com import gltf2_io

        def texture_index(name):
            if name not in self.images:
                image = next((i for i in bpy.data.images if i.name_full == name), None)
                if image is None:
                    raise RenderError(f"image '{name}' is gone")
                data, mime = image_bytes(image, "a Neural BRDF texture")
                if gltf2_plan.images is None:
                    gltf2_plan.images = []
                if gltf2_plan.textures is None:
                    gltf2_plan.textures = []
                gltf2_plan.images.append(
                    gltf2_io.Image(
                        buffer_view=None,
                        extensions=None,
                        extras=None,
                        mime_type=mime,
                        name=name,
                        uri=f"data:{mime};base64," + base64.b64encode(data).decode("ascii"),
                    )
                )
                gltf2_plan.textures.append(
                    gltf2_io.Texture(extensions=None, extras=None, name=name, sampler=None, source=len(gltf2_plan.images) - 1)
                )
                self.images[name] = len(gltf2_plan.textures) - 1
            return self.images[name]

        def resolve(value):
            if isinstance(value, dict):
                if _IMAGE_KEY in value:
                    return {"index": texture_index(value[_IMAGE_KEY]), "texCoord": value.get("texCoord", 0)}
                return {k: resolve(v) for k, v in value.items()}
            if isinstance(value, list):
                return [resolve(v) for v in value]
            return value

        for material in gltf2_plan.materials or []:
            if isinstance(material.extras, dict) and isinstance(material.extras.get("neural"), dict):
                try:
                    material.extras = resolve(material.extras)
                except RenderError as e:
                    print(f"Neural BRDF: {e}: not exported")
                    material.extras.pop("neural", None)


def _on_main_thread(function, test_break):
    """Runs `function` on Blender's main thread: directly when called there (background
    renders), else through a timer while this (render) thread waits, stopping the wait when
    `test_break()` says Esc was pressed. Blender's operators must not run in a render thread."""
    if threading.current_thread() is threading.main_thread():
        return function()
    box = {}
    done = threading.Event()
    abandoned = threading.Event()

    def timer():
        if not abandoned.is_set():
            try:
                box["value"] = function()
            except BaseException as e:  # handed to the waiting thread
                box["error"] = e
        done.set()
        return None

    bpy.app.timers.register(timer, first_interval=0.0)
    while not done.wait(0.1):
        if test_break():
            abandoned.set()
            raise Cancelled("render cancelled (Esc) while exporting")
    if "error" in box:
        raise box["error"]
    return box["value"]


def export_scene(depsgraph, path, test_break):
    """Exports the scene the depsgraph renders with Blender's glTF exporter (extras, cameras,
    lights, renderable objects with modifiers applied, the current frame) to `path` (.gltf +
    .bin + textures). Returns the seconds taken."""
    scene = depsgraph.scene.original
    view_layer = scene.view_layers.get(depsgraph.view_layer.name)

    def export():
        start = time.perf_counter()
        # Evaluate the frame afresh: the exporter reads the objects as the viewport last
        # evaluated them, which may predate the latest edits of their animation.
        scene.frame_set(scene.frame_current, subframe=scene.frame_subframe)
        # Command-line renders (`-f 1`) run without a window, whose context the exporter reads.
        override = {"scene": scene, "active_object": None}
        if view_layer is not None:
            override.update(view_layer=view_layer, active_object=view_layer.objects.active)
        windows = bpy.context.window_manager.windows
        if bpy.context.window is None and len(windows) > 0:
            override["window"] = windows[0]
        with bpy.context.temp_override(**override):
            result = bpy.ops.export_scene.gltf(
                filepath=path,
                check_existing=False,
                export_format='GLTF_SEPARATE',
                export_extras=True,
                export_cameras=True,
                export_lights=True,
                export_yup=True,
                export_apply=True,
                export_animations=False,
                export_current_frame=True,
                use_renderable=True,
                use_active_scene=True,
                will_save_settings=False,
            )
        if 'FINISHED' not in result or not os.path.isfile(path):
            raise RenderError(f"Blender's glTF exporter did not write {path}")
        return time.perf_counter() - start

    try:
        return _on_main_thread(export, test_break)
    except RuntimeError as e:  # the operator's error report, a Python traceback
        lines = [line.strip() for line in str(e).splitlines() if line.strip() and not line.startswith("Location:")]
        raise RenderError(f"Blender's glTF exporter failed: {lines[-1] if lines else e}") from None
