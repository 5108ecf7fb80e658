"""Every scene family builds, for several seeds, into a scene that can be rendered: a camera,
lights or a lit world, content, and a 16x16 render of 1 sample with every pass finite.

    blender -b --factory-startup -P training/datagen/families_test.py    # exit 0 pass, 1 fail
"""
import math
import os
import sys
import tempfile

import bpy
import numpy as np
import OpenImageIO as oiio

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import blender_render  # noqa: E402
import scenes  # noqa: E402

SEEDS = (1, 2)


def check(family, seed, tmp):
    info = scenes.build(family, seed)
    scene = bpy.context.scene
    if scene.camera is None:
        return "no camera"
    if len([o for o in scene.objects if o.type == "MESH"]) < 2 and family != "text":
        return "no content"
    spec = {"frame": [64, 48], "crop": [24, 16, 16, 16], "threads": 1, "raw_dir": tmp}
    blender_render.setup_render(scene, spec)
    path = os.path.join(tmp, f"{family}_{seed}.exr")
    blender_render.render(scene, path, 1, 1)
    buf = oiio.ImageBuf(path)
    px = buf.get_pixels(oiio.FLOAT)
    if px is None or not np.isfinite(px).all():
        return "a pass is not finite"
    if not info.get("camera"):
        return "no camera in the description"
    return None


def main():
    failures = []
    with tempfile.TemporaryDirectory() as tmp:
        for family in scenes.FAMILIES + scenes.EXTRA_FAMILIES:
            for seed in SEEDS:
                try:
                    problem = check(family, seed, tmp)
                except Exception as e:  # noqa: BLE001  a family that cannot build
                    problem = f"{type(e).__name__}: {e}"
                print(f"families_test: {family} seed {seed}: {problem or 'ok'}", flush=True)
                if problem:
                    failures.append(f"{family}:{seed}")
    print(f"families_test: {'FAILED ' + ','.join(failures) if failures else 'all families build and render'}",
          flush=True)
    return 1 if failures else 0


if __name__ == "__main__":
    code = main()
    sys.stdout.flush()
    os._exit(code)
