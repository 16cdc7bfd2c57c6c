# SPDX-License-Identifier: MIT
"""The render engine "Neural BRDF" (`NEURAL_BRDF`).

A render (one per frame and view layer): check the bindings, export the scene
(`export.export_scene`), run

    render scene.gltf --resolution WxH --spp N --max-depth D --seed S --camera CAMERA
           [--material LATENT] [--threads T] --output render.exr --progress-lines

in the export's directory, show its progress in Blender's progress bar, and load the EXR into
the render result. Esc stops `render` as Ctrl-C does (it writes the image rendered so far,
which is loaded) and reports an error. Errors reach Blender's report as one line starting
"Neural BRDF:" (`render`'s own message where it gave one); `render`'s warnings and notes
are reported as warnings.
"""

import os
import shlex
import shutil
import tempfile
import time
import traceback

import bpy

from . import export, runner
from .runner import Cancelled, RenderError

ENGINE = "NEURAL_BRDF"

# Seconds taken by the export and by `render` for the last frame rendered (for scripts that
# time renders, e.g. assets-scripts/addon_vs_cycles.py).
last_timings = {}


def render_size(engine, scene):
    """The image size Blender asks for (the resolution scaled by its percentage)."""
    if engine.resolution_x > 0 and engine.resolution_y > 0:
        return engine.resolution_x, engine.resolution_y
    r = scene.render
    return max(1, r.resolution_x * r.resolution_percentage // 100), max(1, r.resolution_y * r.resolution_percentage // 100)


class NeuralBrdfRenderEngine(bpy.types.RenderEngine):
    bl_idname = ENGINE
    bl_label = "Neural BRDF"
    bl_use_preview = False
    bl_use_shading_nodes_custom = False  # Blender's shader nodes, as Cycles and EEVEE
    bl_use_eevee_viewport = True  # the viewport's Material Preview and Rendered modes use EEVEE

    def esc_pressed(self):
        """Blender's test_break: the user pressed Esc (a method of its own, so that tests can
        simulate Esc: RNA functions such as test_break cannot be overridden)."""
        return self.test_break()

    def render(self, depsgraph):
        try:
            self._render(depsgraph)
        except RenderError as e:
            self.report({'ERROR'}, f"Neural BRDF: {e}")
        except Exception as e:  # a bug: the traceback to the console, one line to the user
            traceback.print_exc()
            self.report({'ERROR'}, f"Neural BRDF: internal error: {type(e).__name__}: {e}")

    def _render(self, depsgraph):
        scene = depsgraph.scene
        settings = scene.neural_brdf
        width, height = render_size(self, scene)
        binary = runner.render_binary(settings)
        latent = runner.latent_path(settings)
        export.check_bindings(depsgraph)
        camera = self.camera_override or scene.camera
        if camera is None or camera.type != 'CAMERA':
            raise RenderError(f"scene '{scene.name}' has no camera")
        _, world_warning = export.world_environment(scene.world)
        if world_warning:
            self.report({'WARNING'}, f"Neural BRDF: {world_warning}")

        keep = bpy.path.abspath(settings.export_dir.strip()) if settings.export_dir.strip() else None
        if keep:
            os.makedirs(keep, exist_ok=True)
            directory = keep
        else:
            directory = tempfile.mkdtemp(prefix="neural-brdf-", dir=bpy.app.tempdir or None)
        try:
            self._render_in(depsgraph, directory, binary, latent, camera, width, height)
        finally:
            if not keep:
                shutil.rmtree(directory, ignore_errors=True)

    def _render_in(self, depsgraph, directory, binary, latent, camera, width, height):
        scene = depsgraph.scene
        settings = scene.neural_brdf
        gltf = os.path.join(directory, "scene.gltf")
        exr = os.path.join(directory, "render.exr")
        if os.path.exists(exr):  # of an earlier render kept in export_dir
            os.remove(exr)
        self.update_stats("", "Neural BRDF: exporting glTF")
        export_seconds = export.export_scene(depsgraph, gltf, self.esc_pressed)
        if self.esc_pressed():
            raise Cancelled("render cancelled (Esc) before it started")

        argv = [
            binary,
            gltf,
            "--resolution", f"{width}x{height}",
            "--spp", str(settings.spp),
            "--max-depth", str(settings.max_depth),
            "--seed", str(settings.seed),
            "--camera", camera.data.name,
        ]
        if latent:
            argv += ["--material", latent]
        if scene.render.threads_mode == 'FIXED':
            argv += ["--threads", str(scene.render.threads)]
        argv += ["--output", exr, "--progress-lines"]
        with open(os.path.join(directory, "command.txt"), "w") as f:
            f.write(" ".join(shlex.quote(a) for a in argv[:-1]) + "\n")

        start = time.perf_counter()
        process = runner.RenderProcess(argv)
        cancelled = False
        self.update_stats("", "Neural BRDF: rendering")
        while not process.done:
            progress = process.poll(0.1)
            if progress is not None:
                self.update_progress(progress)
                self.update_stats("", f"Neural BRDF: rendering {progress * 100:.0f} %")
            if self.esc_pressed():
                cancelled = True
                break
        code = process.stop() if cancelled else process.finish()
        render_seconds = time.perf_counter() - start

        for line in process.stderr:
            if line.startswith(("warning:", "note:")):
                self.report({'WARNING'}, f"Neural BRDF: {line}")
        if cancelled:
            if os.path.isfile(exr):
                self._load(exr, width, height)
                raise Cancelled("render cancelled (Esc): the image holds the samples rendered so far")
            raise Cancelled("render cancelled (Esc)")
        if code != 0:
            raise RenderError(runner.one_line(process.stderr, code))
        if not os.path.isfile(exr):
            raise RenderError(f"render wrote no image ({exr})")
        self._load(exr, width, height)
        last_timings.update(export=export_seconds, render=render_seconds)
        print(
            f"Neural BRDF: frame {scene.frame_current}: export {export_seconds:.2f} s, "
            f"render {render_seconds:.2f} s ({directory})"
        )

    def _load(self, exr, width, height):
        result = self.begin_result(0, 0, width, height)
        try:
            result.layers[0].load_from_file(exr)
        except RuntimeError as e:
            raise RenderError(f"{exr}: cannot load the image into the render result: {e}") from None
        finally:
            self.end_result(result)


# Blender's own panels shown with this engine: those for every engine (the ones that list
# BLENDER_RENDER), plus EEVEE's material, world and light panels, which edit what the glTF
# exporter reads.
EXTRA_PANELS = (
    "EEVEE_MATERIAL_PT_context_material",
    "EEVEE_MATERIAL_PT_surface",
    "EEVEE_MATERIAL_PT_settings",
    "EEVEE_WORLD_PT_surface",
    "DATA_PT_EEVEE_light",
)
EXCLUDED_PANELS = {"VIEWLAYER_PT_filter", "VIEWLAYER_PT_layer_passes"}


def _compatible_panels():
    for panel in bpy.types.Panel.__subclasses__():
        engines = getattr(panel, "COMPAT_ENGINES", None)
        if engines is None or panel.__name__ in EXCLUDED_PANELS:
            continue
        if "BLENDER_RENDER" in engines or panel.__name__ in EXTRA_PANELS:
            yield panel


def register():
    bpy.utils.register_class(NeuralBrdfRenderEngine)
    for panel in _compatible_panels():
        panel.COMPAT_ENGINES.add(ENGINE)


def unregister():
    for panel in _compatible_panels():
        panel.COMPAT_ENGINES.discard(ENGINE)
    bpy.utils.unregister_class(NeuralBrdfRenderEngine)
