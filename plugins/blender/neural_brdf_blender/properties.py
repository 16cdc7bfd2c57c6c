# SPDX-License-Identifier: MIT
"""The add-on's settings: `scene.neural_brdf` (the render) and `material.neural_brdf` (what
a material binds).

A material binds, by `mode`:
- `CODE`: `code` alone (empty: the material renders its own glTF parameters);
- `MIX`: the exact mixture of `code`, `code_b`, `code_c`, `code_d` (the non-empty ones),
  weighted per texel by the R, G, B, A of the image `weights` (linear, normalised);
- `BLEND`: the latent interpolation from `code` to `code_b` at t = channel `channel` of the
  image `weights` (latent codes only);
each with an optional `tint` image (sRGB) multiplying the BRDF. Images are named (by
`weights` and `tint`) rather than pointed to: Blender's glTF exporter copies a material's
custom properties into its extras, and cannot copy a pointer to an image. A code is a latent name of
the scene's latent file, or `merl:PATH.binary` (a MERL table) or `nbrdf:PREFIX` (an NBRDF
network); paths may be relative to the .blend file (`//`).
"""

import bpy
from bpy.props import EnumProperty, IntProperty, PointerProperty, StringProperty

from . import runner


def _search_codes(self, context, edit_text):
    """The latent file's codes for a code field's drop-down (free text is accepted too)."""
    codes, _ = runner.latent_codes(context.scene.neural_brdf)
    text = edit_text.lower()
    return [c for c in codes if text in c.lower()]


def _code(name, description):
    return StringProperty(
        name=name,
        description=description,
        default="",
        search=_search_codes,
        search_options={'SUGGESTION', 'SORT'},
    )


class NeuralBrdfSceneSettings(bpy.types.PropertyGroup):
    render_path: StringProperty(
        name="Render Binary",
        description="The `render` program of the neural-BRDF path tracer (empty: `render` found on PATH)",
        default="",
        subtype='FILE_PATH',
    )
    latent_file: StringProperty(
        name="Latent File",
        description="Latent file (latent.bin) whose codes materials bind (empty: none; bound codes then render "
        "their glTF parameters)",
        default="",
        subtype='FILE_PATH',
    )
    spp: IntProperty(name="Samples", description="Samples per pixel", default=64, min=1, soft_max=4096)
    max_depth: IntProperty(
        name="Max Depth",
        description="Longest light path in segments, as Mitsuba 3's max_depth: 1 = emitters seen directly, "
        "2 = direct lighting, ...; -1 = unlimited",
        default=8,
        min=-1,
        soft_max=64,
    )
    seed: IntProperty(
        name="Seed",
        description="Seed of the random streams: the same seed gives the same image",
        default=0,
        min=0,
    )
    export_dir: StringProperty(
        name="Keep Files In",
        description="Directory receiving the exported glTF (scene.gltf), the command line (command.txt) and the "
        "rendered EXR (render.exr) of the last frame rendered (empty: a temporary directory, removed after the "
        "render)",
        default="",
        subtype='DIR_PATH',
    )


class NeuralBrdfMaterialSettings(bpy.types.PropertyGroup):
    mode: EnumProperty(
        name="Binding",
        description="What the material binds",
        items=[
            ('CODE', "Code", "One latent code, measured table or network (none: the material's glTF parameters)"),
            ('MIX', "Mix", "Up to four codes mixed per texel by the R, G, B, A of an image"),
            ('BLEND', "Blend", "The latent interpolation between two codes at t read from one channel of an image"),
        ],
        default='CODE',
    )
    code: _code(
        "Code",
        "Latent code of the latent file, merl:PATH.binary or nbrdf:PREFIX (empty: the material's own glTF parameters)",
    )
    code_b: _code("Code B", "Second code (mix: weighted by the image's green; blend: the code at t = 1)")
    code_c: _code("Code C", "Third code of a mix (weighted by the image's blue)")
    code_d: _code("Code D", "Fourth code of a mix (weighted by the image's alpha)")
    weights: StringProperty(
        name="Weights",
        description="Image whose R, G, B, A weight the codes of a mix, or whose channel is t of a blend (linear "
        "data: set its colour space to Non-Color; saved or packed as PNG or JPEG)",
        default="",
    )
    channel: IntProperty(
        name="Channel",
        description="Channel of the image holding t of a blend: 0 R, 1 G, 2 B, 3 A",
        default=0,
        min=0,
        max=3,
    )
    tint: StringProperty(
        name="Tint",
        description="Optional image (sRGB, values at most 1) multiplying the bound BRDF",
        default="",
    )

    def codes(self):
        """The codes this binding uses, in order (empty fields left out)."""
        fields = {'CODE': ("code",), 'MIX': ("code", "code_b", "code_c", "code_d"), 'BLEND': ("code", "code_b")}
        return [getattr(self, f).strip() for f in fields[self.mode] if getattr(self, f).strip()]


CLASSES = (NeuralBrdfSceneSettings, NeuralBrdfMaterialSettings)


def register():
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.Scene.neural_brdf = PointerProperty(type=NeuralBrdfSceneSettings)
    bpy.types.Material.neural_brdf = PointerProperty(type=NeuralBrdfMaterialSettings)


def unregister():
    del bpy.types.Material.neural_brdf
    del bpy.types.Scene.neural_brdf
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
