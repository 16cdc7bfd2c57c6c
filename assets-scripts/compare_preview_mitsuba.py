#!/usr/bin/env python3
"""Render the material-preview scene with Mitsuba 3 and with our renderer; compare mean radiance.

Both sides come from one definition, assets-scripts/make_material_preview.py: ours renders
scenes/material-preview/scene.gltf (written by that script), Mitsuba renders
`make_material_preview.mitsuba_scene(sphere_bsdf)` (same meshes, camera, point light,
environment, path tracer with the same max depth; see that function's docstring). The script
prints the per-channel mean radiance of both EXR images and their ratio render / mitsuba (exit
status 1 when one differs from 1 by more than --tolerance), the same over the sphere's interior
pixels (where the sphere's BSDF dominates), and the relative RMSE of 8x8-block means; images and
a summary JSON go to --out-dir.

What the sphere is:
- --preset diffuse (the default without --mitsuba-bsdf): a Lambertian sphere with albedo
  --albedo (default: the preview material's base colour) on both sides. Our renderer has no
  `--bind` form for Lambert, so the script writes a copy of scene.gltf into --out-dir with the
  "preview" material's extras set to {"bsdf": "diffuse"} (buffer and environment referenced by
  relative paths, nothing else changed); Mitsuba gets {"type": "diffuse"} with that albedo.
- --preset metallic-roughness (the default with --mitsuba-bsdf): scene.gltf as is, i.e. our
  GGX/Smith/Schlick copper, or whatever --bind / --render-arg bind the "preview" material to;
  Mitsuba gets `principled` with the same base colour, metallic 1 and roughness. Not exact in
  theory: Mitsuba's microfacet uses the separable Smith G1(wi) G1(wo), ours the
  height-correlated G2 (measured: no difference above the noise at roughness 0.3).
- --preset glass / thin-glass: a copy of scene.gltf whose "preview" material is clear glass
  (KHR_materials_transmission 1, base colour white, metallic 0, --roughness, KHR_materials_ior
  --ior; glass adds KHR_materials_volume with thickness 1 and no absorption, so the sphere is
  solid; without it the surface is thin-walled). Mitsuba gets `dielectric` (roughness 0),
  `roughdielectric` (GGX, alpha = roughness^2) or `thindielectric` with int_ior --ior,
  ext_ior 1. Both scale radiance by 1/eta^2 across the boundary.
- --preset coat: a copy whose "preview" material is a clear coat alone (KHR_materials_clearcoat 1,
  roughness --roughness, over a black base with KHR_materials_specular 0). Mitsuba gets
  `roughplastic` (GGX, alpha = roughness^2, int_ior 1.5, black diffuse): the same lobe, but with
  the exact Fresnel at the microfacet (wo.h) where glTF's layering takes Schlick's at the
  macroscopic angle (0.04 + 0.96 (1 - mu_o)^5) and Mitsuba's separable Smith G1 G1 where ours
  is height-correlated, so the two agree only approximately (no Mitsuba BSDF layers a coat the
  way glTF specifies).
- --mitsuba-bsdf JSON replaces Mitsuba's sphere BSDF, e.g. for a neural BRDF plugin:
      --import plugins/python/my_plugin.py \\
      --mitsuba-bsdf '{"type": "neural_brdf", "filename": "...", "material": "alum-bronze"}' \\
      --bind preview=nbrdf:...    (or --render-arg=--material --render-arg=FILE)
  --import loads a Python module (file path or dotted name) after mi.set_variant, for a plugin
  that registers its BSDF on import or with a module-level register() (called when present):
      --import neural_brdf.mitsuba \
      --mitsuba-bsdf '{"type": "neural_brdf", "filename": "scenes/materials/latent.bin", "material": "chrome"}' \
      --render-arg=--material --render-arg=scenes/materials/latent.bin --bind preview=neural:chrome

- --preset neural-mix / neural-blend: spatially varying neural materials (docs/plugins.md),
  the latent file --latent (default: the shipped scenes/materials/latent.bin) on both sides,
  textures written as PNG into --out-dir (linear, bilinear, repeating; they vary along u only,
  i.e. around the sphere):
  neural-mix: {"neural": {"mix": [A, B], "weights": TEXTURE}} with --codes A,B (default
  dark-red-paint,aluminium) and an 8 x 1 texture of alternating red / green texels, so half the
  sphere's longitudes are A, half B, with bilinear blends of the two in between; Mitsuba gets the
  plugin's {"type": "neural_brdf", "mix": "A, B", "weights": <bitmap, raw>}.
  neural-blend: {"neural": {"blend": [A, B], "t": TEXTURE, "channel": 0}} with --codes A,B
  (default gold-metallic-paint,silver-metallic-paint) and t rising from 0 to 1 over a 16 x 1
  ramp (red channel; --blend-t T: a constant t instead); Mitsuba gets {"type": "neural_brdf",
  "blend": "A, B", "t": <bitmap, raw>} (the renderer's 32-entry palette, neighbours mixed).
  Both import neural_brdf.mitsuba and pass --material LATENT to our renderer.

What the stage is: --stage studio (default) is the scene as it is; --stage constant keeps the
sphere and the camera only, under a constant environment of radiance --constant (both sides:
our glTF copy's extras.environment.color, Mitsuba's `constant` emitter), e.g. a glossy metal
sphere in a constant environment. The render times printed compare the two renderers' speed
(run the script three times for min/median/max).

    python3 assets-scripts/compare_preview_mitsuba.py                  # 128x128, 256 spp, depth 8
    python3 assets-scripts/compare_preview_mitsuba.py --preset metallic-roughness
    python3 assets-scripts/compare_preview_mitsuba.py --preset metallic-roughness --stage constant \
        --resolution 256 --spp 512
    python3 assets-scripts/compare_preview_mitsuba.py --preset glass                   # dielectric
    python3 assets-scripts/compare_preview_mitsuba.py --preset glass --roughness 0.3   # roughdielectric
    python3 assets-scripts/compare_preview_mitsuba.py --preset thin-glass              # thindielectric
    python3 assets-scripts/compare_preview_mitsuba.py --preset neural-mix --spp 64     # textured mix
    python3 assets-scripts/compare_preview_mitsuba.py --preset neural-blend --spp 64   # t ramp
"""

import argparse
import importlib
import importlib.util
import json
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)
import make_material_preview as preview  # noqa: E402
from compare_mitsuba import channel_means, fmt, parse_resolution, run_render, set_variant  # noqa: E402


def diffuse_material(albedo):
    """The preview material's glTF fields for a Lambertian sphere of `albedo`."""
    return {"pbrMetallicRoughness": {"baseColorFactor": [float(c) for c in albedo] + [1.0],
                                     "metallicFactor": 0.0, "roughnessFactor": 1.0},
            "extras": {"bsdf": "diffuse"}}


def glass_material(roughness, ior, thin):
    """The preview material's glTF fields for clear glass: KHR_materials_transmission 1 on a
    white dielectric of `roughness` (perceptual; GGX alpha = roughness^2) and KHR_materials_ior
    `ior`; a solid sphere (KHR_materials_volume, thickness > 0, no absorption) unless `thin`."""
    extensions = {"KHR_materials_transmission": {"transmissionFactor": 1.0},
                  "KHR_materials_ior": {"ior": ior}}
    if not thin:
        extensions["KHR_materials_volume"] = {"thicknessFactor": 1.0}
    return {"pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0],
                                     "metallicFactor": 0.0, "roughnessFactor": float(roughness)},
            "extensions": extensions, "extras": {}}


def glass_mitsuba_bsdf(roughness, ior, thin):
    """Mitsuba 3's BSDF for glass_material(): `thindielectric`, `dielectric` or `roughdielectric`
    (GGX, alpha = roughness^2, visible-normal sampling)."""
    if thin:
        if roughness != 0.0:
            raise SystemExit("Mitsuba 3 has no rough thin dielectric: thin-glass compares at --roughness 0 only")
        return {"type": "thindielectric", "int_ior": ior, "ext_ior": 1.0}
    if roughness == 0.0:
        return {"type": "dielectric", "int_ior": ior, "ext_ior": 1.0}
    return {"type": "roughdielectric", "distribution": "ggx", "alpha": roughness ** 2,
            "int_ior": ior, "ext_ior": 1.0}


def coat_material(roughness):
    """The preview material's glTF fields for a clear coat alone: KHR_materials_clearcoat 1 of
    `roughness` over a black dielectric whose own specular is off (KHR_materials_specular 0),
    so all the sphere reflects is the coat's lobe."""
    return {"pbrMetallicRoughness": {"baseColorFactor": [0.0, 0.0, 0.0, 1.0],
                                     "metallicFactor": 0.0, "roughnessFactor": 1.0},
            "extensions": {"KHR_materials_clearcoat": {"clearcoatFactor": 1.0,
                                                       "clearcoatRoughnessFactor": float(roughness)},
                           "KHR_materials_specular": {"specularFactor": 0.0}},
            "extras": {}}


def staged_gltf(scene, out_dir, material=None, constant=None, name="scene"):
    """A copy of `scene` in `out_dir` named `name`.gltf (buffer and environment referenced by
    relative paths): with `material` (glTF material fields, e.g. diffuse_material()), its
    preview material gets those fields; with `constant`, the stage is the sphere alone (no
    ground, no key light) under a constant environment of that radiance. Returns its path."""
    with open(scene) as f:
        gltf = json.load(f)
    scene_dir = os.path.dirname(os.path.abspath(scene))
    rel = os.path.relpath(scene_dir, out_dir)
    for buffer in gltf.get("buffers", []):
        uri = buffer.get("uri", "")
        if uri and ":" not in uri:
            buffer["uri"] = os.path.join(rel, uri).replace(os.sep, "/")
    for s in gltf.get("scenes", []):
        env = s.get("extras", {}).get("environment", {})
        if "image" in env:
            env["image"] = os.path.join(rel, env["image"]).replace(os.sep, "/")
    if material is not None:
        found = False
        for m in gltf["materials"]:
            if m.get("name") == preview.PREVIEW_MATERIAL:
                m.update(json.loads(json.dumps(material)))
                found = True
        if not found:
            raise SystemExit(f"{scene}: no material named {preview.PREVIEW_MATERIAL!r}")
        used = set(gltf.get("extensionsUsed", []))
        used.update(material.get("extensions", {}).keys())
        if used:
            gltf["extensionsUsed"] = sorted(used)
    if constant is not None:
        keep = {"sphere", "camera"}
        for s in gltf.get("scenes", []):
            s["nodes"] = [i for i in s["nodes"] if gltf["nodes"][i].get("name") in keep]
            s.setdefault("extras", {})["environment"] = {"color": [float(constant)] * 3}
    path = os.path.join(out_dir, f"{name}{'-constant' if constant is not None else ''}.gltf")
    with open(path, "w") as f:
        json.dump(gltf, f, indent=1)
    return path


NEURAL_DEFAULT_CODES = {"neural-mix": "dark-red-paint,aluminium",
                        "neural-blend": "gold-metallic-paint,silver-metallic-paint"}


def neural_texels(preset, blend_t=None):
    """The preset's texture (uint8 RGB, 1 row): alternating full-red / full-green texels (mix
    weights of A and B), or t = i / 15 over 16 texels in the red channel (or a constant t)."""
    if preset == "neural-mix":
        rgb = np.zeros((1, 8, 3), np.uint8)
        rgb[0, 0::2, 0] = 255
        rgb[0, 1::2, 1] = 255
        return rgb
    t = np.full(16, blend_t, np.float64) if blend_t is not None else np.arange(16) / 15.0
    rgb = np.zeros((1, len(t), 3), np.uint8)
    rgb[0, :, 0] = np.round(255 * t).astype(np.uint8)
    return rgb


def neural_textured(preset, args, out_dir, constant):
    """(our staged glTF, Mitsuba's sphere BSDF, label) for the neural-mix / neural-blend presets."""
    from PIL import Image

    codes = [c.strip() for c in (args.codes or NEURAL_DEFAULT_CODES[preset]).split(",")]
    latent = os.path.abspath(args.latent)
    label = f"{preset}-{'-'.join(codes)}" + (f"-t{args.blend_t:g}" if preset == "neural-blend" and args.blend_t is not None else "")
    png = os.path.join(out_dir, f"{label}.png")
    Image.fromarray(neural_texels(preset, args.blend_t), "RGB").save(png)
    texture = {"index": 0, "texCoord": 0}
    if preset == "neural-mix":
        neural = {"mix": codes, "weights": texture}
    else:
        neural = {"blend": codes, "t": texture, "channel": 0}
    path = staged_gltf(args.scene, out_dir, {"extras": {"neural": neural}}, constant, f"scene-{label}")
    with open(path) as f:
        gltf = json.load(f)
    linear, repeat = 9729, 10497
    gltf["images"] = [{"uri": os.path.basename(png)}]
    gltf["samplers"] = [{"magFilter": linear, "minFilter": linear, "wrapS": repeat, "wrapT": repeat}]
    gltf["textures"] = [{"source": 0, "sampler": 0}]
    with open(path, "w") as f:
        json.dump(gltf, f, indent=1)
    bitmap = {"type": "bitmap", "filename": png, "raw": True, "filter_type": "bilinear", "wrap_mode": "repeat"}
    bsdf = {"type": "neural_brdf", "filename": latent}
    if preset == "neural-mix":
        bsdf.update({"mix": ", ".join(codes), "weights": bitmap})
    else:
        bsdf.update({"blend": ", ".join(codes), "t": bitmap, "channel": 0})
    return path, bsdf, label


def import_plugin(spec):
    """Imports a module given as a .py path or a dotted name (importable from the repo root)."""
    if spec.endswith(".py") or os.sep in spec:
        name = os.path.splitext(os.path.basename(spec))[0]
        module_spec = importlib.util.spec_from_file_location(name, spec)
        module = importlib.util.module_from_spec(module_spec)
        sys.modules[name] = module
        module_spec.loader.exec_module(module)
        return module
    if ROOT not in sys.path:
        sys.path.insert(0, ROOT)
    return importlib.import_module(spec)


def render_mitsuba(args, sphere_bsdf, width, height, out_exr):
    mi = set_variant(args.variant)
    import drjit as dr

    if args.threads:
        dr.set_thread_count(args.threads)
    for spec in args.imports:
        module = import_plugin(spec)
        if callable(getattr(module, "register", None)):
            module.register()  # e.g. neural_brdf.mitsuba
    t0 = time.perf_counter()
    definition = preview.mitsuba_scene(
        sphere_bsdf,
        width=width,
        height=height,
        max_depth=args.max_depth,
        scene_dir=os.path.dirname(os.path.abspath(args.scene)),
        spp=args.spp,
        env_supersample=args.env_supersample,
    )
    if args.stage == "constant":
        del definition["ground"], definition["key-light"]
        definition["environment"] = {"type": "constant",
                                     "radiance": {"type": "rgb", "value": [args.constant] * 3}}
    scene = mi.load_dict(definition)
    t_load = time.perf_counter() - t0
    t0 = time.perf_counter()
    img = np.array(mi.render(scene, spp=args.spp, seed=args.seed))
    t_render = time.perf_counter() - t0
    mi.Bitmap(img).write(out_exr)
    return {
        "variant": mi.variant(), "mitsuba_version": mi.__version__, "threads": dr.thread_count(),
        "sphere_bsdf": sphere_bsdf, "env_supersample": args.env_supersample,
        "load_seconds": t_load, "wall_seconds": t_render,
        "mean_rgb": channel_means(img).tolist(), "exr": out_exr,
    }, img


def render_ours(args, scene, width, height, out_exr, out_json):
    cmd = [args.render_bin, scene, "--spp", str(args.spp), "--resolution", f"{width}x{height}",
           "--max-depth", str(args.max_depth), "--seed", str(args.seed),
           "--output", out_exr, "--stats", out_json]
    for b in args.bind:
        cmd += ["--bind", b]
    cmd += args.render_arg
    stats, img, t_proc = run_render(cmd, out_exr, out_json)
    return {
        "command": cmd, "wall_seconds": float(stats.get("wall_seconds", t_proc)),
        "mean_rgb": channel_means(img).tolist(), "exr": out_exr, "stats": stats,
    }, img


def sphere_mask(width, height, shrink=0.95):
    """Pixels whose centre ray passes within shrink * SPHERE_RADIUS of the sphere's centre (the
    sphere's interior in the image, away from its silhouette), from the scene's constants."""
    origin = np.array(preview.camera_position())
    forward = -origin / np.linalg.norm(origin)
    right = np.cross(forward, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    tan_half = np.tan(np.radians(preview.CAMERA_YFOV_DEGREES) / 2)
    x = (2 * (np.arange(width) + 0.5) / width - 1) * tan_half * width / height
    y = (1 - 2 * (np.arange(height) + 0.5) / height) * tan_half
    d = forward + x[None, :, None] * right + y[:, None, None] * up
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    dist = np.linalg.norm(np.cross(-origin, d), axis=-1)
    return dist < shrink * preview.SPHERE_RADIUS


def block_relative_rmse(a, b, n=8):
    """Relative RMSE of n x n block means of b against a (suppresses per-pixel noise)."""
    h, w = (a.shape[0] // n) * n, (a.shape[1] // n) * n

    def blocks(x):
        return x[:h, :w, :3].astype(np.float64).reshape(h // n, n, w // n, n, 3).mean((1, 3))

    ba, bb = blocks(a), blocks(b)
    return float(np.sqrt(np.mean((bb - ba) ** 2)) / np.mean(ba))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=__doc__)
    ap.add_argument("--variant", default="llvm_ad_rgb", help="Mitsuba variant (default llvm_ad_rgb)")
    ap.add_argument("--resolution", type=parse_resolution, default=(128, 128), help="WxH or N (default 128)")
    ap.add_argument("--spp", type=int, default=256)
    ap.add_argument("--max-depth", type=int, default=8)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--threads", type=int, default=0, help="Mitsuba threads (default: all cores)")
    ap.add_argument("--preset", choices=["diffuse", "metallic-roughness", "glass", "thin-glass", "coat", "neural-mix",
                                         "neural-blend"], default=None,
                    help="our sphere: diffuse = a Lambert copy of the scene, metallic-roughness = scene.gltf "
                         "as is, glass / thin-glass = a copy with clear glass of --roughness and --ior (solid, "
                         "or thin-walled); and Mitsuba's sphere unless --mitsuba-bsdf is given (default: "
                         "diffuse, or metallic-roughness with --mitsuba-bsdf)")
    ap.add_argument("--roughness", type=float, default=0.0,
                    help="glass presets: perceptual roughness (0 = smooth: Mitsuba's dielectric; > 0: "
                         "roughdielectric with GGX alpha = roughness^2)")
    ap.add_argument("--ior", type=float, default=1.5, help="glass presets: index of refraction (default 1.5)")
    ap.add_argument("--latent", default=os.path.join(ROOT, "scenes", "materials", "latent.bin"),
                    help="neural presets: the latent file (default: the shipped one)")
    ap.add_argument("--codes", default=None, metavar="A,B",
                    help="neural presets: the two codes (default: see the presets above)")
    ap.add_argument("--blend-t", type=float, default=None,
                    help="neural-blend: a constant t instead of the 0-to-1 ramp")
    ap.add_argument("--stage", choices=["studio", "constant"], default="studio",
                    help="studio = the scene as it is (ground, key light, studio environment); constant = "
                         "the sphere alone in a constant environment of radiance --constant")
    ap.add_argument("--constant", type=float, default=1.0, help="radiance of the constant stage (default 1)")
    ap.add_argument("--albedo", type=float, nargs=3, default=preview.PREVIEW_BASE_COLOR[:3],
                    metavar=("R", "G", "B"), help="albedo of the diffuse preset (default: preview base colour)")
    ap.add_argument("--mitsuba-bsdf", type=json.loads, default=None,
                    help="JSON load_dict dictionary of the sphere's BSDF on the Mitsuba side (replaces the "
                         "preset's)")
    ap.add_argument("--bind", action="append", default=[], metavar="MATERIAL=BINDING",
                    help="passed to our renderer as --bind (repeatable), e.g. preview=nbrdf:PREFIX")
    ap.add_argument("--render-arg", action="append", default=[],
                    help="extra argument for our renderer (repeatable; use --render-arg=--material)")
    ap.add_argument("--import", dest="imports", action="append", default=[], metavar="MODULE",
                    help="Python module (path or dotted name) imported after mi.set_variant, "
                         "e.g. one registering a plugin BSDF (repeatable)")
    ap.add_argument("--env-supersample", type=int, default=4,
                    help="resample the environment k times finer for Mitsuba so its bilinear look-up "
                         "matches our nearest-texel one (1 = the file as is; default 4)")
    ap.add_argument("--scene", default=os.path.join(preview.DEFAULT_SCENE_DIR, "scene.gltf"))
    ap.add_argument("--render-bin", default=os.path.join(ROOT, "target", "release", "render"))
    ap.add_argument("--out-dir", default=os.path.join(ROOT, "target", "compare-preview-mitsuba"))
    ap.add_argument("--mitsuba-only", action="store_true", help="skip our renderer")
    ap.add_argument("--tolerance", type=float, default=0.01,
                    help="exit status 1 when a channel's ratio differs from 1 by more (default 0.01)")
    args = ap.parse_args()

    width, height = args.resolution
    out_dir = os.path.abspath(args.out_dir)
    os.makedirs(out_dir, exist_ok=True)
    preset = args.preset or ("metallic-roughness" if args.mitsuba_bsdf is not None else "diffuse")
    constant = args.constant if args.stage == "constant" else None
    if preset == "diffuse":
        sphere_bsdf = {"type": "diffuse", "reflectance": {"type": "rgb", "value": list(args.albedo)}}
        our_scene = None if args.mitsuba_only else staged_gltf(
            args.scene, out_dir, diffuse_material(args.albedo), constant, "scene-diffuse-sphere")
    elif preset in ("glass", "thin-glass"):
        thin = preset == "thin-glass"
        sphere_bsdf = glass_mitsuba_bsdf(args.roughness, args.ior, thin)
        our_scene = staged_gltf(args.scene, out_dir, glass_material(args.roughness, args.ior, thin), constant,
                                f"scene-{preset}-r{args.roughness:g}-ior{args.ior:g}")
    elif preset == "coat":
        sphere_bsdf = {"type": "roughplastic", "distribution": "ggx", "alpha": max(args.roughness, 0.01) ** 2,
                       "int_ior": 1.5, "ext_ior": 1.0, "diffuse_reflectance": {"type": "rgb", "value": [0.0] * 3}}
        our_scene = staged_gltf(args.scene, out_dir, coat_material(args.roughness), constant,
                                f"scene-coat-r{args.roughness:g}")
    elif preset in ("neural-mix", "neural-blend"):
        our_scene, sphere_bsdf, neural_label = neural_textured(preset, args, out_dir, constant)
        if "neural_brdf.mitsuba" not in args.imports:
            args.imports.append("neural_brdf.mitsuba")
        args.render_arg += ["--material", os.path.abspath(args.latent)]
    else:
        our_scene = args.scene if constant is None else staged_gltf(args.scene, out_dir, None, constant)
        sphere_bsdf = {"type": "principled",
                       "base_color": {"type": "rgb", "value": preview.PREVIEW_BASE_COLOR[:3]},
                       "metallic": 1.0, "roughness": preview.PREVIEW_ROUGHNESS}
    label = {"glass": f"{preset}-r{args.roughness:g}-ior{args.ior:g}", "thin-glass": f"{preset}-r{args.roughness:g}-ior{args.ior:g}",
             "coat": f"coat-r{args.roughness:g}"}.get(preset, preset)
    if preset in ("neural-mix", "neural-blend"):
        label = neural_label
    if args.mitsuba_bsdf is not None:
        sphere_bsdf, label = args.mitsuba_bsdf, f"{preset}-custom"
    if constant is not None:
        label += "-constant"
    tag = f"preview-{label}_{width}x{height}_{args.spp}spp_d{args.max_depth}"

    mit, mimg = render_mitsuba(args, sphere_bsdf, width, height,
                               os.path.join(out_dir, f"{tag}_mitsuba.exr"))
    print(f"Mitsuba {mit['mitsuba_version']} {mit['variant']} ({mit['threads']} threads), {width}x{height}, "
          f"{args.spp} spp, max_depth {args.max_depth}, sphere {json.dumps(sphere_bsdf)}")
    print(f"  load {mit['load_seconds']:.2f} s, render {mit['wall_seconds']:.2f} s")
    print(f"  mean RGB {fmt(mit['mean_rgb'])}  -> {mit['exr']}")
    summary = {"sphere": label, "resolution": [width, height], "spp": args.spp,
               "max_depth": args.max_depth, "mitsuba": mit}
    status = 0
    if not args.mitsuba_only:
        ours, oimg = render_ours(args, our_scene, width, height, os.path.join(out_dir, f"{tag}_render.exr"),
                                 os.path.join(out_dir, f"{tag}_render.json"))
        ratio = np.array(ours["mean_rgb"]) / np.array(mit["mean_rgb"])
        print(f"render: {ours['wall_seconds']:.2f} s")
        print(f"  mean RGB {fmt(ours['mean_rgb'])}  -> {ours['exr']}")
        print(f"ratio render / mitsuba per channel: {fmt(ratio, 4)}")
        summary.update(render=ours, ratio=ratio.tolist())
        if oimg.shape[:2] == mimg.shape[:2]:
            mask = sphere_mask(width, height)
            ms, os_ = channel_means(mimg[mask]), channel_means(oimg[mask])
            print(f"sphere interior ({int(mask.sum())} pixels): mitsuba {fmt(ms)}, render {fmt(os_)}, "
                  f"ratio {fmt(os_ / ms, 4)}")
            summary.update(sphere_pixels=int(mask.sum()), sphere_mean_rgb={"mitsuba": ms.tolist(),
                           "render": os_.tolist()}, sphere_ratio=(os_ / ms).tolist())
            rrmse = block_relative_rmse(mimg, oimg)
            print(f"relative RMSE of 8x8-block means: {rrmse:.4f}")
            summary["block_relative_rmse"] = rrmse
        if np.any(np.abs(ratio - 1.0) > args.tolerance):
            print(f"MISMATCH: a channel differs by more than {100 * args.tolerance:g} %")
            status = 1
    out_json = os.path.join(out_dir, f"{tag}_summary.json")
    with open(out_json, "w") as f:
        json.dump(summary, f, indent=1)
    print(f"summary -> {out_json}")
    return status


if __name__ == "__main__":
    sys.exit(main())
