"""The K seeds of a level are independent: their sample variance is the variance of their mean.

    blender -b --factory-startup -P training/datagen/seed_test.py    # exit 0 pass, 1 fail

A scene whose every pixel's noise is the pixel filter's (an emitting checker far finer than a
pixel: no lighting, no bounces), rendered as blender_render.py renders a level: 8 seeds of
1 and of 2 spp (render_jobs, render). The mean's squared error against a 2048-spp reference
must be what the seeds' variance of the mean predicts (ratio in [0.7, 1.4]). Seeds that
shared a sample would fail it: in Cycles 3.4 a pixel's first sample lies at the same place
whatever the seed, and 8 seeds of 1 spp starting at sample 0 give 8 identical images (a
variance of 0 against a mean squared error of about 0.08 here).
"""
import os
import sys
import tempfile

import bpy
import numpy as np
import OpenImageIO as oiio

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import blender_render  # noqa: E402


def checker_scene(size):
    scene = bpy.context.scene
    for obj in list(scene.objects):
        if obj.type != "CAMERA":
            bpy.data.objects.remove(obj)
    camera = next(o for o in scene.objects if o.type == "CAMERA")
    camera.location, camera.rotation_euler = (0, 0, 10), (0, 0, 0)
    bpy.ops.mesh.primitive_plane_add(size=20)
    material = bpy.data.materials.new("checker")
    material.use_nodes = True
    nodes, links = material.node_tree.nodes, material.node_tree.links
    for node in list(nodes):
        nodes.remove(node)
    checker = nodes.new("ShaderNodeTexChecker")
    checker.inputs["Scale"].default_value = 300  # a few squares per pixel
    emission = nodes.new("ShaderNodeEmission")
    output = nodes.new("ShaderNodeOutputMaterial")
    links.new(checker.outputs["Color"], emission.inputs["Color"])
    links.new(emission.outputs["Emission"], output.inputs["Surface"])
    bpy.context.object.data.materials.append(material)
    scene.world = None
    blender_render.setup_render(scene, {"frame": [size, size], "crop": [0, 0, size, size]})
    return scene


def read(path):
    buf = oiio.ImageBuf(path)
    names = list(buf.spec().channelnames)
    pixels = buf.get_pixels(oiio.FLOAT).reshape(-1, len(names)).astype(np.float64)
    return pixels[:, [names.index(f"ViewLayer.Combined.{c}") for c in "RGB"]]


def main():
    scene = checker_scene(32)
    failures = 0
    with tempfile.TemporaryDirectory() as tmp:
        spec = {"levels": [8, 16], "K": 8, "ref_spp": 2048, "ref_K": 1}
        images = {}
        for tag, n, k, s, spp, seed, offset in blender_render.render_jobs(spec):
            path = os.path.join(tmp, f"{tag}_s{s}.exr")
            blender_render.render(scene, path, spp, seed, sample_offset=offset)
            images.setdefault(tag, []).append(read(path))
        reference = images.pop("ref")[0]
        for tag, seeds in sorted(images.items()):
            seeds = np.stack(seeds)
            mean = seeds.mean(axis=0)
            variance = seeds.var(axis=0, ddof=1).mean() / len(seeds)
            error = ((mean - reference) ** 2).mean()
            ratio = error / max(variance, 1e-30)
            ok = 0.7 <= ratio <= 1.4
            failures += not ok
            print(f"seed_test: {tag} ({len(seeds)} seeds): squared error {error:.5f}, variance "
                  f"of the mean {variance:.5f}, ratio {ratio:.3f} {'ok' if ok else 'FAIL (not in [0.7, 1.4])'}",
                  flush=True)
    return failures


if __name__ == "__main__":
    try:
        code = 1 if main() else 0
    except BaseException:
        import traceback
        traceback.print_exc()
        code = 1
    sys.stdout.flush()
    os._exit(code)
