# SPDX-License-Identifier: MIT
"""Panels: Render Properties > Neural BRDF (the scene's settings) and Material Properties >
Neural BRDF (the material's binding, with the latent file's codes to pick from)."""

import bpy

from . import runner
from .engine import ENGINE


class _EnginePanel:
    bl_space_type = 'PROPERTIES'
    bl_region_type = 'WINDOW'
    COMPAT_ENGINES = {ENGINE}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES


class NEURAL_BRDF_PT_render(_EnginePanel, bpy.types.Panel):
    bl_label = "Neural BRDF"
    bl_context = "render"

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        settings = context.scene.neural_brdf
        layout.prop(settings, "render_path")
        try:
            runner.render_binary(settings)
        except runner.RenderError as e:
            layout.label(text=str(e), icon='ERROR')
        layout.prop(settings, "latent_file")
        codes, error = runner.latent_codes(settings)
        if error:
            layout.label(text=error, icon='ERROR')
        elif codes:
            layout.label(text=f"{len(codes)} codes", icon='INFO')
        col = layout.column(align=True)
        col.prop(settings, "spp")
        col.prop(settings, "max_depth")
        col.prop(settings, "seed")
        layout.prop(settings, "export_dir")


class NEURAL_BRDF_PT_material(_EnginePanel, bpy.types.Panel):
    bl_label = "Neural BRDF"
    bl_context = "material"

    @classmethod
    def poll(cls, context):
        return super().poll(context) and context.material is not None

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        layout.use_property_decorate = False
        binding = context.material.neural_brdf
        settings = context.scene.neural_brdf
        layout.prop(binding, "mode")
        codes, error = runner.latent_codes(settings)
        if binding.mode == 'CODE':
            layout.prop(binding, "code")
        elif binding.mode == 'MIX':
            for field in ("code", "code_b", "code_c", "code_d"):
                layout.prop(binding, field)
            layout.prop_search(binding, "weights", bpy.data, "images")
        else:
            layout.prop(binding, "code")
            layout.prop(binding, "code_b")
            layout.prop_search(binding, "weights", bpy.data, "images")
            layout.prop(binding, "channel")
        layout.prop_search(binding, "tint", bpy.data, "images")
        if error:
            layout.label(text=error, icon='ERROR')
        elif not settings.latent_file.strip():
            layout.label(text="No latent file (Render Properties > Neural BRDF)", icon='INFO')
        unknown = [c for c in binding.codes() if ":" not in c and c not in codes]
        if codes and unknown:
            layout.label(text=f"Not in the latent file: {', '.join(unknown)}", icon='ERROR')
        if codes:
            wm = context.window_manager
            box = layout.box()
            box.prop(
                wm,
                "neural_brdf_show_codes",
                text=f"Codes ({len(codes)})",
                icon='TRIA_DOWN' if wm.neural_brdf_show_codes else 'TRIA_RIGHT',
                emboss=False,
            )
            if wm.neural_brdf_show_codes:
                flow = box.grid_flow(row_major=True, columns=0, even_columns=True, align=True)
                for code in codes:
                    flow.operator(NEURAL_BRDF_OT_pick_code.bl_idname, text=code, depress=code == binding.code).code = code


class NEURAL_BRDF_OT_pick_code(bpy.types.Operator):
    """Bind this code (the material's first code)"""

    bl_idname = "neural_brdf.pick_code"
    bl_label = "Pick Code"
    bl_options = {'REGISTER', 'UNDO', 'INTERNAL'}

    code: bpy.props.StringProperty()

    @classmethod
    def poll(cls, context):
        return getattr(context, "material", None) is not None

    def execute(self, context):
        context.material.neural_brdf.code = self.code
        return {'FINISHED'}


CLASSES = (NEURAL_BRDF_OT_pick_code, NEURAL_BRDF_PT_render, NEURAL_BRDF_PT_material)


def register():
    bpy.types.WindowManager.neural_brdf_show_codes = bpy.props.BoolProperty(
        name="Show Codes", description="List the latent file's codes", default=False
    )
    for cls in CLASSES:
        bpy.utils.register_class(cls)


def unregister():
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
    del bpy.types.WindowManager.neural_brdf_show_codes
