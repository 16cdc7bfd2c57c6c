#!/usr/bin/env python3
"""Writes the procedural studio environment of the material-preview scene.

Output: scenes/material-preview/studio.exr (512 x 256, equirectangular, RGB half floats,
ZIP compression), linear radiance in W/(m^2 sr).

Equirectangular convention (the renderer's environment module, renderer/src/lights/
environment.rs): a world direction d (y up) maps to image coordinates (u, v) in [0, 1)^2 with

    u = 0.5 + atan2(d.x, -d.z) / (2 pi),    v = acos(d.y) / pi,

v = 0 being the top row (+y), u = 0.5 the image centre looking toward -z (away from the
preview camera, which sits on +z). Pixel (column i, row j) is the direction of its centre,
u = (i + 0.5) / W, v = (j + 0.5) / H.

Content: a dim vertical gradient (cool at the zenith, neutral at the horizon), a darker warm
"floor" below the horizon, and three soft boxes with smooth edges: a large warm key above-left
of the camera, a cool fill to the right, and a neutral strip behind the sphere for a rim. The
boxes are rectangles in the gnomonic (tangent-plane) projection about their centre directions,
so they look like flat rectangular light panels.

Usage: python3 assets-scripts/make_studio_envmap.py [output.exr]
Needs numpy and the OpenEXR Python package (pip install OpenEXR).
"""

import os
import sys

import numpy as np
import OpenEXR

WIDTH, HEIGHT = 512, 256


def directions(width, height):
    """World directions of the pixel centres, shape (height, width, 3)."""
    u = (np.arange(width) + 0.5) / width
    v = (np.arange(height) + 0.5) / height
    phi = (u - 0.5) * 2.0 * np.pi  # atan2(d.x, -d.z)
    theta = v * np.pi  # acos(d.y)
    phi, theta = np.meshgrid(phi, theta)
    sin_theta = np.sin(theta)
    return np.stack(
        [sin_theta * np.sin(phi), np.cos(theta), -sin_theta * np.cos(phi)], axis=-1
    )


def direction_to_uv(d):
    """The convention above, for checking: (u, v) of unit directions d (..., 3)."""
    u = 0.5 + np.arctan2(d[..., 0], -d[..., 2]) / (2.0 * np.pi)
    v = np.arccos(np.clip(d[..., 1], -1.0, 1.0)) / np.pi
    return np.mod(u, 1.0), v


def smoothstep(edge0, edge1, x):
    t = np.clip((x - edge0) / (edge1 - edge0), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def soft_box(d, centre, up_hint, half_width, half_height, softness):
    """Weight in [0, 1] of a rectangular panel facing the origin from direction `centre`.

    half_width, half_height: half extents in the tangent plane at unit distance (tan of the
    angular half sizes); softness: width of the smooth edge in the same units.
    """
    c = np.asarray(centre, dtype=np.float64)
    c /= np.linalg.norm(c)
    right = np.cross(np.asarray(up_hint, dtype=np.float64), c)
    right /= np.linalg.norm(right)
    up = np.cross(c, right)
    cos_c = d @ c
    front = cos_c > 1e-3
    safe = np.where(front, cos_c, 1.0)
    a = np.abs((d @ right) / safe)
    b = np.abs((d @ up) / safe)
    wa = 1.0 - smoothstep(half_width - softness, half_width + softness, a)
    wb = 1.0 - smoothstep(half_height - softness, half_height + softness, b)
    return np.where(front, wa * wb, 0.0)


def studio(width=WIDTH, height=HEIGHT):
    d = directions(width, height)
    y = d[..., 1:2]
    # Upper hemisphere: neutral grey at the horizon to a slightly cool, dimmer zenith.
    horizon = np.array([0.16, 0.16, 0.16])
    zenith = np.array([0.07, 0.08, 0.10])
    floor = np.array([0.045, 0.04, 0.035])
    t_up = np.clip(y, 0.0, 1.0) ** 0.6
    sky = horizon * (1.0 - t_up) + zenith * t_up
    # Lower hemisphere: a darker warm floor, blended over a narrow band at the horizon.
    below = smoothstep(0.0, -0.08, y)
    radiance = sky * (1.0 - below) + floor * below

    boxes = [
        # (centre direction, up hint, half width, half height, softness, radiance)
        ((-0.55, 0.65, 0.55), (0, 1, 0), 0.45, 0.30, 0.08, (9.0, 8.2, 7.0)),  # warm key
        ((0.85, 0.20, 0.35), (0, 1, 0), 0.22, 0.45, 0.06, (2.2, 2.6, 3.2)),  # cool fill
        ((0.10, 0.35, -0.95), (0, 1, 0), 0.70, 0.06, 0.03, (5.0, 5.0, 5.0)),  # rim strip
    ]
    for centre, up_hint, hw, hh, soft, colour in boxes:
        w = soft_box(d, centre, up_hint, hw, hh, soft)[..., None]
        radiance = radiance * (1.0 - w) + np.asarray(colour) * w
    return radiance.astype(np.float32)


def check_convention():
    d = directions(8, 4)
    u, v = direction_to_uv(d)
    expected_u = (np.arange(8) + 0.5) / 8
    expected_v = (np.arange(4) + 0.5) / 4
    assert np.allclose(u, expected_u[None, :]), "u convention"
    assert np.allclose(v, expected_v[:, None]), "v convention"
    centre = np.array([[0.0, 0.0, -1.0]])
    cu, cv = direction_to_uv(centre)
    assert np.isclose(cu[0], 0.5) and np.isclose(cv[0], 0.5), "image centre looks toward -z"


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    default = os.path.join(here, "..", "scenes", "material-preview", "studio.exr")
    out = os.path.normpath(sys.argv[1] if len(sys.argv) > 1 else default)
    check_convention()
    rgb = studio()
    os.makedirs(os.path.dirname(out), exist_ok=True)
    header = {
        "compression": OpenEXR.ZIP_COMPRESSION,
        "type": OpenEXR.scanlineimage,
        "envmap": OpenEXR.ENVMAP_LATLONG,
    }
    channels = {"RGB": rgb.astype(np.float16)}
    with OpenEXR.File(header, channels) as exr:
        exr.write(out)
    print(
        f"wrote {out}: {WIDTH}x{HEIGHT}, {os.path.getsize(out)} bytes, "
        f"radiance min {rgb.min():.3f} mean {rgb.mean():.3f} max {rgb.max():.3f}"
    )


if __name__ == "__main__":
    main()
