# SPDX-License-Identifier: MIT
"""Neural BRDF: render Blender scenes with the `render` path tracer and its neural and
measured materials.

The add-on registers the render engine "Neural BRDF" (`NEURAL_BRDF`). A render (F12,
Ctrl-F12, `blender -b file.blend -E NEURAL_BRDF -f 1`) exports the evaluated scene with
Blender's own glTF exporter, runs `render` on it and loads the image into the render
result. A material binds a latent code (or a measured table, `merl:PATH`, or an NBRDF
network, `nbrdf:PREFIX`) in Material Properties > Neural BRDF; the binding is written into
the exported glTF as the material extras `render` reads, also when the scene is exported by
hand with File > Export > glTF 2.0 while the add-on is enabled, so that the file renders the
same outside Blender.

Modules: `properties` (the settings), `export` (the glTF export and the exporter hooks that
write the bindings), `runner` (finding and running `render`, listing a latent file's codes),
`engine` (the render engine), `ui` (the panels).
"""

bl_info = {
    "name": "Neural BRDF",
    "author": "Neural-BRDF path tracer authors",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "Properties > Render > Render Engine > Neural BRDF",
    "description": "Render with the neural-BRDF path tracer: latent codes, measured tables and networks as materials",
    "doc_url": "",
    "category": "Render",
}

if "properties" in locals():  # F8 / "Reload Scripts"
    import importlib

    for _module in (runner, properties, export, engine, ui):  # noqa: F821
        importlib.reload(_module)
else:
    from . import runner, properties, export, engine, ui

# Blender's glTF exporter looks for this name in every enabled add-on and calls its hooks.
glTF2ExportUserExtension = export.BindingsExtension


def register():
    properties.register()
    engine.register()
    ui.register()


def unregister():
    ui.unregister()
    engine.unregister()
    properties.unregister()
