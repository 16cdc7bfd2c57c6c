#!/usr/bin/env python3
"""Compares our render of a scene with a Cycles reference, region by region.

    python3 assets-scripts/compare_cycles.py OURS.exr CYCLES.exr [--png OUT.png]
        [--exposure STOPS] [--diff-scale S] [--max-kb KB] [--no-png]
        [--regions PRESET|FILE.json] [--repeat OURS2.exr CYCLES2.exr]

OURS.exr: `target/release/render scenes/feature-showcase/scene.gltf --resolution 256x256 -o ...`;
CYCLES.exr: `blender ... --python assets-scripts/cycles_reference.py -- ... --resolution 256x256`
(both linear RGB, same resolution). Prints the mean radiance per channel of both images and
the ratio ours / Cycles, for the whole image and for named pixel boxes picked on a 256 x 256
render (at another resolution they are scaled), then writes a side-by-side PNG: ours | Cycles |
difference. `--regions` picks the boxes: a preset, `feature-showcase` (the default, REGIONS;
PNG docs/images/feature-showcase-vs-cycles.png) or `glass` (GLASS_REGIONS, the scene of
make_glass_scene.py; PNG docs/images/glass-vs-cycles.png), or a JSON file holding a list of
[name, x0, y0, x1, y1] boxes on the 256 x 256 grid (PNG as for the default preset).

`--repeat OURS2.exr CYCLES2.exr`: a second pair rendered with other seeds. The table then
shows the means of both pairs, and a last column "seed spread": half the difference between
the two pairs' ratios ours / Cycles (largest over the channels), i.e. roughly one standard
a one-sample estimate of the noise in the ratio of the averaged pairs (its expected value is
0.8 times that ratio's standard deviation). The PNG shows the first pair.

The first two panels share one exposure (`--exposure`, stops, default 0), are clamped to
[0, 1] and sRGB-encoded (no tone mapping, like `render -o x.png --tonemap clamp`). The third
shows the luminance difference ours - Cycles times `--diff-scale` (default 4): red where ours
is brighter, blue where Cycles is brighter, black where they agree (sRGB-encoded too, so small
differences stay visible). Single fireflies show up as isolated dots. The PNG is written
with 8 bits per channel, or, when that is larger than `--max-kb` (default 300), with the low
bits dropped (7, then 6, ... bits: noisy renders compress badly; 7 bits is visually the same).

EXR reading: the OpenEXR module if installed, else Mitsuba 3's `mi.Bitmap` (scalar_rgb).
Needs numpy and Pillow.
"""

import argparse
import os
import sys

import numpy as np

try:
    from PIL import Image, ImageOps
except ImportError:  # pragma: no cover
    sys.exit("compare_cycles.py needs Pillow: python3 -m pip install pillow")

REPO = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
DEFAULT_PNG = os.path.join(REPO, "docs", "images", "feature-showcase-vs-cycles.png")
GLASS_PNG = os.path.join(REPO, "docs", "images", "glass-vs-cycles.png")
REFERENCE_SIZE = 256

# (name, x0, y0, x1, y1): pixel boxes [x0, x1) x [y0, y1) on the 256 x 256 image (x right,
# y down), chosen by looking at the render; each lies inside the object it is named after.
REGIONS = [
    ("sky (environment)", 0, 0, 256, 30),
    ("ground far (tiles, sun)", 0, 34, 256, 56),
    ("ground near (tiles, sun)", 0, 210, 256, 256),
    ("fence shadow on ground", 84, 140, 124, 190),
    ("fence (with ground through it)", 24, 118, 74, 196),
    ("emissive sign", 124, 72, 152, 88),
    ("brick slab (front face)", 24, 84, 76, 106),
    ("cylinder (ior 1.8, specular)", 92, 60, 110, 96),
    ("copper sphere", 196, 64, 234, 108),
    ("stained glass", 156, 82, 186, 116),
    ("rocks", 140, 140, 245, 205),
]

# The scene of make_glass_scene.py at 256 x 256 (clear glass sphere centred near (129, 125),
# radius 47 px; rough glass sphere near (34, 130), radius 30 px). Inside the clear sphere the
# scene behind is seen upside down: ground tiles at the top, the gold sphere behind it on the
# right, the sky at the bottom.
GLASS_REGIONS = [
    ("sky (environment)", 0, 0, 256, 70),
    ("clear glass (inscribed box)", 96, 92, 162, 159),
    ("ground seen through clear glass", 98, 95, 120, 125),
    ("sky seen through clear glass", 100, 135, 122, 152),
    ("gold sphere through clear glass", 130, 112, 155, 140),
    ("rough glass (inscribed box)", 14, 110, 54, 150),
    ("clear glass's shadow on ground", 165, 185, 200, 205),
    ("rough glass's shadow (caustic)", 40, 165, 70, 180),
    ("gold sphere (direct view)", 224, 106, 246, 126),
    ("open ground (sunlit, near)", 0, 215, 90, 256),
]

PRESETS = {
    "feature-showcase": (REGIONS, DEFAULT_PNG),
    "glass": (GLASS_REGIONS, GLASS_PNG),
}


def load_regions(spec):
    """(regions, default PNG) for a preset name or a JSON file of [name, x0, y0, x1, y1]."""
    if spec in PRESETS:
        return PRESETS[spec]
    if not os.path.isfile(spec):
        sys.exit("compare_cycles.py: --regions takes %s or a JSON file; %r is neither" % (
            " or ".join(sorted(PRESETS)), spec))
    import json
    with open(spec) as f:
        boxes = json.load(f)
    try:
        regions = [(str(n), int(x0), int(y0), int(x1), int(y1)) for n, x0, y0, x1, y1 in boxes]
    except (TypeError, ValueError):
        sys.exit("compare_cycles.py: %s must hold a list of [name, x0, y0, x1, y1]" % spec)
    return regions, DEFAULT_PNG


def read_exr(path):
    """Linear RGB float32 array (height, width, 3)."""
    try:
        import OpenEXR
        import Imath
        f = OpenEXR.InputFile(path)
        dw = f.header()["dataWindow"]
        w, h = dw.max.x - dw.min.x + 1, dw.max.y - dw.min.y + 1
        pt = Imath.PixelType(Imath.PixelType.FLOAT)
        return np.stack([np.frombuffer(f.channel(c, pt), np.float32).reshape(h, w)
                         for c in "RGB"], axis=-1)
    except ImportError:
        pass
    try:
        import mitsuba as mi
    except ImportError:
        sys.exit("compare_cycles.py needs OpenEXR (pip install OpenEXR) or Mitsuba 3 "
                 "(pip install mitsuba) to read EXR files")
    mi.set_variant("scalar_rgb")
    a = np.array(mi.Bitmap(path), dtype=np.float32)
    if a.ndim == 2:
        a = a[..., None]
    if a.shape[2] == 1:
        a = np.repeat(a, 3, axis=2)
    return a[..., :3]


def srgb8(linear):
    x = np.clip(linear, 0.0, 1.0)
    x = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return (x * 255.0 + 0.5).astype(np.uint8)


def luminance(a):
    return a[..., 0] * 0.2126 + a[..., 1] * 0.7152 + a[..., 2] * 0.0722


def fmt3(v):
    return " ".join("%.4f" % x for x in v)


def region_mean(a, box):
    x0, y0, x1, y1 = box
    return a[y0:y1, x0:x1].reshape(-1, 3).astype(np.float64).mean(0)


def table(pairs, regions):
    """pairs: [(ours, cycles)], one or two; with two, the means of both and the seed spread."""
    h, w = pairs[0][0].shape[:2]
    rows = [("whole image", 0, 0, w, h)]
    for name, x0, y0, x1, y1 in regions:
        sx, sy = w / REFERENCE_SIZE, h / REFERENCE_SIZE
        rows.append((name, round(x0 * sx), round(y0 * sy), round(x1 * sx), round(y1 * sy)))
    spread = len(pairs) > 1
    print(("%-32s %-19s %-22s %-22s %-22s%s" % (
        "region", "box x0,y0-x1,y1", "ours R G B", "Cycles R G B", "ours/Cycles R G B",
        " seed spread" if spread else "")).rstrip())
    for name, x0, y0, x1, y1 in rows:
        box = (x0, y0, x1, y1)
        mo = np.mean([region_mean(o, box) for o, _ in pairs], axis=0)
        mc = np.mean([region_mean(c, box) for _, c in pairs], axis=0)
        ratio = mo / np.maximum(mc, 1e-12)
        extra = ""
        if spread:
            r = [region_mean(o, box) / np.maximum(region_mean(c, box), 1e-12) for o, c in pairs]
            extra = " %.4f" % (np.abs(r[0] - r[1]).max() / 2)
        print(("%-32s %-19s %-22s %-22s %-22s%s" % (
            name, "%d,%d-%d,%d" % box, fmt3(mo), fmt3(mc), fmt3(ratio), extra)).rstrip())


def side_by_side(ours, cycles, exposure, diff_scale, gap=4):
    k = 2.0 ** exposure
    d = (luminance(ours) - luminance(cycles)) * diff_scale
    diff = np.zeros_like(ours)
    diff[..., 0] = np.maximum(d, 0.0)
    diff[..., 2] = np.maximum(-d, 0.0)
    h, w = ours.shape[:2]
    out = np.full((h, 3 * w + 2 * gap, 3), 255, np.uint8)
    for i, panel in enumerate((srgb8(ours * k), srgb8(cycles * k), srgb8(diff))):
        out[:, i * (w + gap):i * (w + gap) + w] = panel
    return Image.fromarray(out)


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("ours")
    p.add_argument("cycles")
    p.add_argument("--png", help="side-by-side output (default: docs/images/"
                                 "glass-vs-cycles.png with --regions glass, else docs/images/"
                                 "feature-showcase-vs-cycles.png)")
    p.add_argument("--no-png", action="store_true", help="print the table only")
    p.add_argument("--exposure", type=float, default=0.0, help="stops, both renders")
    p.add_argument("--diff-scale", type=float, default=4.0)
    p.add_argument("--max-kb", type=float, default=300.0,
                   help="drop low bits (7, then 6, 5 bits per channel) until the PNG fits")
    p.add_argument("--regions", default="feature-showcase",
                   help="preset (%s) or JSON file of [name, x0, y0, x1, y1] boxes on the "
                        "256 x 256 grid (default %%(default)s)" % ", ".join(sorted(PRESETS)))
    p.add_argument("--repeat", nargs=2, metavar=("OURS2", "CYCLES2"),
                   help="a second pair rendered with other seeds: averaged, with the seed spread")
    args = p.parse_args()
    regions, default_png = load_regions(args.regions)
    args.png = args.png or default_png

    paths = [args.ours, args.cycles] + (args.repeat or [])
    images = [read_exr(path) for path in paths]
    for path, a in zip(paths, images):
        if a.shape != images[0].shape:
            sys.exit("compare_cycles.py: sizes differ: %s vs %s" % (images[0].shape, a.shape))
        bad = ~np.isfinite(a)
        if bad.any():
            print("warning: %s has %d non-finite values (set to 0)" % (path, bad.sum()))
            a[bad] = 0.0
    pairs = [(images[i], images[i + 1]) for i in range(0, len(images), 2)]
    ours, cycles = pairs[0]
    table(pairs, regions)
    if not args.no_png:
        os.makedirs(os.path.dirname(os.path.abspath(args.png)), exist_ok=True)
        image = side_by_side(ours, cycles, args.exposure, args.diff_scale)
        bits = 8
        while True:
            out = image if bits == 8 else ImageOps.posterize(image, bits)
            out.save(args.png, optimize=True)
            size = os.path.getsize(args.png)
            if size <= args.max_kb * 1024 or bits <= 5:
                break
            bits -= 1
        print("wrote %s (%d bytes, %d bits per channel)" % (args.png, size, bits))


if __name__ == "__main__":
    main()
