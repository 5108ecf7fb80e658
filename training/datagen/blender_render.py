"""Render one crop inside Blender: every seed of every sample count and the reference.

    blender -b --factory-startup -t 2 -P blender_render.py -- --spec spec.json

spec.json holds: family, seed, crop, frame, levels, K, ref_spp, ref_K, raw_dir, exposure, and
optionally adaptive_levels, adaptive_threshold, sky, only_tags (render only those levels),
and for a frame of a sequence: sequence (N frames), frame_number (1..N), seed_offset (added to
every Cycles seed): the scene is animated (scenes.add_motion), set to that frame, and the
Vector pass (motion vectors, motion blur off) is written.
Writes raw per-seed multilayer EXRs ``L<NNNN>_s<k>.exr`` / ``ref_s<k>.exr`` into raw_dir and
``render_log.json`` (scene description, per-render seeds, spp, CPU and wall seconds).  All
seeds of all levels render in this one process (a Cycles seed is only reproducible within a
process, and start-up costs ~2 s per process).
"""
import json
import math
import os
import random
import sys
import time

import bpy

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import scenes  # noqa: E402


def parse():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    if len(argv) != 2 or argv[0] != "--spec":
        raise SystemExit("usage: blender -b --factory-startup -P blender_render.py -- --spec spec.json")
    with open(argv[1]) as f:
        return json.load(f)


def setup_render(scene, spec):
    scene.render.engine = "CYCLES"
    cy = scene.cycles
    cy.device = "CPU"
    cy.use_adaptive_sampling = False
    cy.use_denoising = False
    cy.use_preview_denoising = False
    cy.sample_clamp_direct = 0.0
    cy.sample_clamp_indirect = 0.0
    cy.blur_glossy = 0.0
    cy.sampling_pattern = "PROGRESSIVE_MULTI_JITTER"
    cy.use_animated_seed = False
    cy.pixel_filter_type = "BLACKMAN_HARRIS"
    cy.filter_width = 1.5
    cy.caustics_reflective = True
    cy.caustics_refractive = True
    cy.max_bounces = 12
    cy.diffuse_bounces = 4
    cy.glossy_bounces = 4
    cy.transmission_bounces = 12
    cy.transparent_max_bounces = 8
    cy.use_auto_tile = False
    cy.time_limit = 0.0
    scene.render.film_transparent = False
    scene.render.use_persistent_data = bool(spec.get("persistent", True))
    scene.view_settings.view_transform = "Standard"
    scene.view_settings.look = "None"
    fw, fh = spec["frame"]
    x0, y0, cw, ch = spec["crop"]
    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = fw, fh, 100
    r.pixel_aspect_x = r.pixel_aspect_y = 1.0
    r.use_border = True
    r.use_crop_to_border = True
    # Blender's border is in [0,1] with y measured from the bottom
    r.border_min_x, r.border_max_x = x0 / fw, (x0 + cw) / fw
    r.border_min_y, r.border_max_y = 1.0 - (y0 + ch) / fh, 1.0 - y0 / fh
    r.threads_mode = "FIXED"
    r.threads = int(spec.get("threads", 2))
    s = r.image_settings
    s.file_format = "OPEN_EXR_MULTILAYER"
    s.color_depth = "32"
    s.exr_codec = "ZIP"
    vl = scene.view_layers[0]
    vl.name = "ViewLayer"
    vl.use_pass_combined = True
    vl.use_pass_z = True
    vl.use_pass_normal = True
    vl.use_pass_diffuse_direct = vl.use_pass_diffuse_indirect = vl.use_pass_diffuse_color = True
    vl.use_pass_glossy_direct = vl.use_pass_glossy_indirect = vl.use_pass_glossy_color = True
    trans = bool(spec.get("trans_passes", True))
    vl.use_pass_transmission_direct = vl.use_pass_transmission_indirect = trans
    vl.use_pass_transmission_color = trans
    vl.use_pass_emit = True
    vl.use_pass_environment = True
    vl.cycles.denoising_store_passes = True
    if spec.get("sequence"):
        r.use_motion_blur = False  # Cycles writes the Vector pass only without motion blur
        vl.use_pass_vector = True


def render(scene, path, spp, seed, adaptive_threshold=None, sample_offset=0):
    """One render of `spp` samples with Cycles seed `seed`, starting at sample `sample_offset`.

    The K seeds of a level must be independent for their sample variance to be the variance
    of their mean. In Cycles 3.4 they are not when each starts at sample 0: a pixel's first
    sample takes the same position in the pixel whatever the seed (seeds of 1 spp give the
    same image wherever the noise is the pixel filter's, as on sub-pixel detail and small
    emitters). Seed k of n spp therefore renders samples [k n, (k+1) n) of its own seed, and
    frame f of a sequence starts past frame f-1's samples, so that only one render of a
    level ever uses sample 0 (main()).
    """
    scene.cycles.use_adaptive_sampling = adaptive_threshold is not None
    if adaptive_threshold is not None:
        scene.cycles.adaptive_threshold = adaptive_threshold
        scene.cycles.adaptive_min_samples = 0  # Cycles' automatic minimum
    scene.cycles.samples = spp
    scene.cycles.seed = seed
    scene.cycles.sample_offset = sample_offset
    scene.render.filepath = path
    c0, w0 = time.process_time(), time.perf_counter()
    bpy.ops.render.render(write_still=True)
    return time.process_time() - c0, time.perf_counter() - w0


def auto_exposure(scene, spec):
    """Pick a film exposure so the crop's median luminance is ~target (one cheap 8-spp render)."""
    import numpy as np
    import OpenImageIO as oiio
    path = os.path.join(spec["raw_dir"], "expo.exr")
    cpu, wall = render(scene, path, 8, 999983)
    buf = oiio.ImageBuf(path)
    names = list(buf.spec().channelnames)
    px = buf.get_pixels(oiio.FLOAT).reshape(buf.spec().height, buf.spec().width, -1)
    rgb = px[..., [names.index(f"ViewLayer.Combined.{c}") for c in "RGB"]]
    lum = rgb @ np.array([0.2126, 0.7152, 0.0722], dtype=np.float32)
    med = float(np.median(lum))
    mean = float(np.mean(lum))
    level = med if med > 1e-4 else mean
    target = float(spec.get("exposure_target", 0.25))
    expo = 1.0 if level <= 1e-7 else min(max(target / level, 1 / 256), 4096.0)
    os.remove(path)
    return {"median_luminance_at_1": med, "mean_luminance_at_1": mean, "film_exposure": expo,
            "cpu_s": cpu, "wall_s": wall}


def render_jobs(spec):
    """Every render of a crop: (tag, level spp, K, seed index, spp, Cycles seed, sample offset)."""
    jobs = []
    for li, n in enumerate(spec["levels"]):
        k = min(spec["K"], n)
        for s in range(k):
            jobs.append(("L%04d" % n, n, k, s, n // k, 1 + 100 * li + s))
    for li, n in enumerate(spec.get("adaptive_levels", [])):
        k = min(spec["K"], n)
        for s in range(k):
            jobs.append(("A%04d" % n, n, k, s, n // k, 50001 + 100 * li + s))
    rk = spec["ref_K"]
    for s in range(rk):
        jobs.append(("ref", spec["ref_spp"], rk, s, spec["ref_spp"] // rk, 100000 + s))
    if spec.get("only_tags"):  # re-render some levels of a crop (the seeds stay theirs)
        jobs = [j for j in jobs if j[0] in spec["only_tags"]]
    seed_offset = int(spec.get("seed_offset", 0))
    frame_index = int(spec.get("frame_number", 1)) - 1 if spec.get("sequence") else 0
    # render()'s docstring says why each render starts at its own sample.
    return [(tag, n, k, s, spp, seed + seed_offset, frame_index * n + s * spp)
            for tag, n, k, s, spp, seed in jobs]


def main():
    spec = parse()
    os.makedirs(spec["raw_dir"], exist_ok=True)
    t0 = time.perf_counter()
    info = scenes.build(spec["family"], spec["seed"])
    if spec.get("sky") is not None:
        aspect = spec["frame"][1] / spec["frame"][0]
        info["camera"]["levelled_for_sky"] = scenes.level_camera(spec["sky"], aspect)
    if spec.get("sequence"):
        info["motion"] = scenes.add_motion(spec["family"], spec["seed"], int(spec["sequence"]),
                                           spec["frame"], spec["crop"])
        bpy.context.scene.frame_set(int(spec["frame_number"]))
        info["motion"]["frame_number"] = int(spec["frame_number"])
    build_s = time.perf_counter() - t0
    scene = bpy.context.scene
    setup_render(scene, spec)
    log = {"blender_version": bpy.app.version_string, "scene": info, "build_s": build_s,
           "renders": []}
    if spec.get("exposure", "auto") == "auto":
        ex = auto_exposure(scene, spec)
        scene.cycles.film_exposure = ex["film_exposure"]
        log["exposure"] = ex
    else:
        scene.cycles.film_exposure = float(spec["exposure"])
        log["exposure"] = {"film_exposure": float(spec["exposure"])}
    for tag, n, k, s, spp, seed, sample_offset in render_jobs(spec):
        path = os.path.join(spec["raw_dir"], f"{tag}_s{s}.exr")
        adaptive = spec.get("adaptive_threshold") if tag.startswith("A") else None
        cpu, wall = render(scene, path, spp, seed, adaptive, sample_offset)
        log["renders"].append({"tag": tag, "level_spp": n, "K": k, "index": s, "spp": spp,
                               "seed": seed, "sample_offset": sample_offset,
                               "file": os.path.basename(path),
                               "cpu_s": round(cpu, 3), "wall_s": round(wall, 3)})
        print(f"[datagen] {tag} seed {seed} {spp} spp: {wall:.2f} s wall, {cpu:.2f} s cpu",
              flush=True)
    log["total_wall_s"] = time.perf_counter() - t0
    with open(os.path.join(spec["raw_dir"], "render_log.json"), "w") as f:
        json.dump(log, f, indent=1)


if __name__ == "__main__":  # run by blender -P (seed_test.py imports it)
    try:
        main()
    except BaseException as e:  # make Blender exit non-zero on any failure
        import traceback
        traceback.print_exc()
        sys.stdout.flush()
        os._exit(1)
