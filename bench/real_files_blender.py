"""The files of bench/real_files, rendered by Blender as a TD's scene writes them (run inside
Blender; bench/real_files starts it):

    blender -b --factory-startup -t 2 -P bench/real_files_blender.py -- OUT W H SPP REF_SPP

One scene of training/datagen (an interior, seed 4601), its lights in light group "key" and its
world in "sky", two view layers "BG" and "FG" (FG without the Diffuse/Glossy passes), written:
- OUT/layers.exr, OUT/layers_ref.exr: the multilayer EXR as Blender writes it, half float,
  DWAA (ref: float, ZIP): Combined, light groups, Denoising Data, Diff/Gloss/Trans Dir/Ind/Col,
  Emit, Env of every view layer;
- OUT/fileout.exr, OUT/fileout_ref.exr: the compositor's File Output node (multilayer, half,
  DWAA) fed BG's passes by socket name: Image, Denoising Albedo, ...;
- OUT/beauty.png: the 8-bit PNG a Standard view transform writes (sRGB);
- OUT/seed1.exr, OUT/seed2.exr: two seeds of SPP/2 samples (float, ZIP);
- OUT/seq.0001.exr, OUT/seq.0002.exr (and _ref): a plain two-frame sequence, the camera moving,
  with the Vector pass (Cycles writes it without motion blur).
"""
import os
import sys

import bpy

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(REPO, "training", "datagen"))
import scenes  # noqa: E402

LAYER_PASSES = ["DiffDir", "DiffInd", "DiffCol", "GlossDir", "GlossInd", "GlossCol"]
FILEOUT_SOCKETS = ["Denoising Albedo", "Denoising Normal", "Denoising Depth"] + LAYER_PASSES


def view_layer(vl, light_passes):
    vl.use_pass_combined = True
    vl.use_pass_z = True
    vl.use_pass_normal = True
    for kind in ("diffuse", "glossy", "transmission"):
        for part in ("direct", "indirect", "color"):
            setattr(vl, f"use_pass_{kind}_{part}", light_passes)
    vl.use_pass_emit = vl.use_pass_environment = light_passes
    vl.cycles.denoising_store_passes = True
    for group in ("key", "sky"):
        if group not in vl.lightgroups:
            vl.lightgroups.add(name=group)


def setup(scene, w, h):
    scene.render.engine = "CYCLES"
    cy = scene.cycles
    cy.device = "CPU"
    cy.use_adaptive_sampling = False
    cy.use_denoising = cy.use_preview_denoising = False
    cy.use_animated_seed = False
    r = scene.render
    r.resolution_x, r.resolution_y, r.resolution_percentage = w, h, 100
    r.threads_mode = "FIXED"
    r.threads = 2
    r.use_motion_blur = False
    scene.view_settings.view_transform = "Standard"
    for ob in scene.objects:
        if ob.type == "LIGHT" or (ob.type == "MESH" and any(
                s.material and s.material.node_tree and any(
                    n.type == "EMISSION" for n in s.material.node_tree.nodes)
                for s in ob.material_slots)):
            ob.lightgroup = "key"
    if scene.world:
        scene.world.lightgroup = "sky"
    bg = scene.view_layers[0]
    bg.name = "BG"
    fg = scene.view_layers.new("FG")
    view_layer(bg, True)
    view_layer(fg, False)
    for vl in (bg, fg):
        vl.use_pass_vector = True


def file_output(scene, base, depth, codec):
    scene.use_nodes = True
    tree = scene.node_tree
    for n in [n for n in tree.nodes if n.type == "OUTPUT_FILE"]:
        tree.nodes.remove(n)
    rl = next(n for n in tree.nodes if n.type == "R_LAYERS")
    rl.layer = "BG"
    fo = tree.nodes.new("CompositorNodeOutputFile")
    fo.base_path = base
    fo.format.file_format = "OPEN_EXR_MULTILAYER"
    fo.format.color_depth = depth
    fo.format.exr_codec = codec
    fo.layer_slots.clear()
    fo.layer_slots.new("Image")
    tree.links.new(rl.outputs["Image"], fo.inputs["Image"])
    for name in FILEOUT_SOCKETS:
        fo.layer_slots.new(name)
        tree.links.new(rl.outputs[name], fo.inputs[name])


def render(scene, path, spp, seed, fmt, depth, codec, fileout=None, animation=False):
    s = scene.render.image_settings
    s.file_format = fmt
    s.color_depth = depth
    if fmt == "OPEN_EXR_MULTILAYER":
        s.exr_codec = codec
    else:
        s.color_mode = "RGB"
    scene.cycles.samples = spp
    scene.cycles.seed = seed
    scene.render.filepath = path
    if fileout:
        file_output(scene, fileout, depth if fmt == "OPEN_EXR_MULTILAYER" else "16", codec)
    else:
        scene.use_nodes = False
    if animation:
        bpy.ops.render.render(animation=True)
    else:
        bpy.ops.render.render(write_still=True)


def main():
    out, w, h, spp, ref_spp = sys.argv[sys.argv.index("--") + 1:]
    w, h, spp, ref_spp = int(w), int(h), int(spp), int(ref_spp)
    os.makedirs(out, exist_ok=True)
    scenes.build("interior", 4601)
    scene = bpy.context.scene
    setup(scene, w, h)
    scene.frame_set(1)
    for tag, n, depth, codec in (("", spp, "16", "DWAA"), ("_ref", ref_spp, "32", "ZIP")):
        render(scene, os.path.join(out, f"layers{tag}.exr"), n, 7, "OPEN_EXR_MULTILAYER", depth,
               codec, fileout=os.path.join(out, f"fileout{tag}_"))
        os.replace(os.path.join(out, f"fileout{tag}_0001.exr"),
                   os.path.join(out, f"fileout{tag}.exr"))
    render(scene, os.path.join(out, "beauty.png"), spp, 7, "PNG", "8", None)
    # Two seeds of half the samples each (each its own Sample Offset: Cycles 3.4's seeds
    # share their first sample), for a render with a variance (RenderMan's mse).
    for k in (0, 1):
        scene.cycles.sample_offset = k * (spp // 2)
        render(scene, os.path.join(out, f"seed{k + 1}.exr"), spp // 2, 11 + k,
               "OPEN_EXR_MULTILAYER", "32", "ZIP")
    scene.cycles.sample_offset = 0
    # The sequence: the camera trucks sideways by a few pixels' worth between the frames.
    cam = scene.camera
    cam.keyframe_insert("location", frame=1)
    cam.location.x += 0.05
    cam.keyframe_insert("location", frame=2)
    scene.frame_start, scene.frame_end = 1, 2
    for tag, n, depth, codec in (("", spp, "16", "DWAA"), ("_ref", ref_spp, "32", "ZIP")):
        render(scene, os.path.join(out, f"seq{tag}.####"), n, 7, "OPEN_EXR_MULTILAYER", depth,
               codec, animation=True)


if __name__ == "__main__":
    try:
        main()
    except BaseException:
        import traceback
        traceback.print_exc()
        sys.stdout.flush()
        os._exit(1)
