#!/usr/bin/env python3
"""Packs the Blender add-on for Edit > Preferences > Add-ons > Install... (Blender 4.2 and
later: Install from Disk...):

    python3 plugins/blender/make_zip.py [OUTPUT.zip]

writes OUTPUT.zip (default target/neural_brdf_blender.zip) holding
neural_brdf_blender/*.py, with fixed timestamps (the same bytes every time).
"""

import os
import sys
import zipfile

HERE = os.path.dirname(os.path.abspath(__file__))
PACKAGE = "neural_brdf_blender"


def main():
    if len(sys.argv) > 2 or any(a.startswith("-") for a in sys.argv[1:]):
        sys.exit(__doc__.strip().split("\n\n")[1])
    repo = os.path.dirname(os.path.dirname(HERE))
    out = os.path.abspath(sys.argv[1]) if len(sys.argv) == 2 else os.path.join(repo, "target", PACKAGE + ".zip")
    os.makedirs(os.path.dirname(out), exist_ok=True)
    sources = sorted(f for f in os.listdir(os.path.join(HERE, PACKAGE)) if f.endswith(".py"))
    with zipfile.ZipFile(out, "w", zipfile.ZIP_DEFLATED) as z:
        for name in sources:
            info = zipfile.ZipInfo(f"{PACKAGE}/{name}", date_time=(2020, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            with open(os.path.join(HERE, PACKAGE, name), "rb") as f:
                z.writestr(info, f.read())
    print(f"wrote {out} ({len(sources)} files)")


if __name__ == "__main__":
    main()
