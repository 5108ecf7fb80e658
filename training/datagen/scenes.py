"""Procedural scene families for the Cycles dataset generator (runs inside Blender 3.4).

Everything is built from scratch with bpy: no external assets.  ``build(family, seed, ...)``
clears the current scene, builds a randomised scene of the given family and returns a
JSON-serialisable description of the parameters that were drawn.

Every family draws one of several *stages* (the overall layout: closed room, corridor,
indirectly lit room, room with a sunlit window, open ground, city blocks, terrain,
colonnade, studio cyclorama) and one of several *arrangements* of its content (cluster, row,
grid, pile), so one family covers very different layouts across seeds.
"""
import math
import random

import bpy
import numpy as np
from mathutils import Vector

FAMILIES = ["interior", "exterior", "texture", "bump", "metal", "glass", "emissive", "fine", "dof"]
# Families a dataset has only when asked for (--families, the n2n preset): not in the default
# rotation, so that the default datasets' crops keep their families. scenes_more.py builds
# all but caustics.
EXTRA_FAMILIES = ["caustics", "window", "many_lights", "screens", "volume", "subsurface", "foliage",
                  "motion_blur", "water", "glossy", "carpaint", "anisotropic", "text", "hdri", "night"]

TEXTURES = ["checker", "noise", "voronoi", "brick", "wave", "magic"]


# ----------------------------------------------------------------------------------------
# small helpers
# ----------------------------------------------------------------------------------------
def clear_scene():
    for ob in list(bpy.data.objects):
        bpy.data.objects.remove(ob, do_unlink=True)
    for coll in (bpy.data.meshes, bpy.data.materials, bpy.data.lights, bpy.data.cameras,
                 bpy.data.worlds, bpy.data.particles, bpy.data.node_groups):
        for item in list(coll):
            coll.remove(item)


def rand_color(rng, sat=(0.2, 0.9), val=(0.2, 0.85)):
    import colorsys
    h = rng.random()
    s = rng.uniform(*sat)
    v = rng.uniform(*val)
    return colorsys.hsv_to_rgb(h, s, v)


def link(nt, a, b):
    nt.links.new(a, b)


def new_material(name):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    nt = m.node_tree
    p = nt.nodes["Principled BSDF"]
    return m, nt, p


def set_p(p, **kw):
    names = {
        "base": "Base Color", "metallic": "Metallic", "rough": "Roughness", "spec": "Specular",
        "transmission": "Transmission", "ior": "IOR", "coat": "Clearcoat",
        "coat_rough": "Clearcoat Roughness", "aniso": "Anisotropic",
        "aniso_rot": "Anisotropic Rotation", "emission": "Emission",
        "estrength": "Emission Strength", "sheen": "Sheen", "trans_rough": "Transmission Roughness",
    }
    for k, v in kw.items():
        inp = p.inputs[names[k]]
        if k in ("base", "emission"):
            inp.default_value = (v[0], v[1], v[2], 1.0)
        else:
            inp.default_value = v


def texture_node(nt, rng, kind, scale):
    """A procedural texture on object coordinates; returns (color_socket, fac_socket, info)."""
    coord = nt.nodes.new("ShaderNodeTexCoord")
    mapping = nt.nodes.new("ShaderNodeMapping")
    link(nt, coord.outputs["Object"], mapping.inputs["Vector"])
    mapping.inputs["Scale"].default_value = (scale, scale, scale)
    mapping.inputs["Rotation"].default_value = (rng.uniform(0, 6.3), rng.uniform(0, 6.3),
                                                rng.uniform(0, 6.3))
    mapping.inputs["Location"].default_value = (rng.uniform(-5, 5), rng.uniform(-5, 5),
                                                rng.uniform(-5, 5))
    info = {"texture": kind, "scale": round(scale, 3)}
    if kind == "checker":
        t = nt.nodes.new("ShaderNodeTexChecker")
        t.inputs["Scale"].default_value = 1.0
    elif kind == "noise":
        t = nt.nodes.new("ShaderNodeTexNoise")
        t.inputs["Detail"].default_value = rng.uniform(2, 15)
        t.inputs["Roughness"].default_value = rng.uniform(0.4, 0.75)
        t.inputs["Distortion"].default_value = rng.choice([0.0, 0.0, rng.uniform(0, 3)])
    elif kind == "voronoi":
        t = nt.nodes.new("ShaderNodeTexVoronoi")
        t.feature = rng.choice(["F1", "F2", "DISTANCE_TO_EDGE"])
        t.distance = rng.choice(["EUCLIDEAN", "MANHATTAN", "CHEBYCHEV"])
        info["feature"] = t.feature
    elif kind == "brick":
        t = nt.nodes.new("ShaderNodeTexBrick")
        t.inputs["Scale"].default_value = 1.0
        t.inputs["Mortar Size"].default_value = rng.uniform(0.01, 0.05)
        t.inputs["Mortar"].default_value = (*rand_color(rng, val=(0.1, 0.9)), 1)
    elif kind == "wave":
        t = nt.nodes.new("ShaderNodeTexWave")
        t.wave_type = rng.choice(["BANDS", "RINGS"])
        t.wave_profile = rng.choice(["SIN", "SAW", "TRI"])
        t.inputs["Distortion"].default_value = rng.uniform(0, 12)
        t.inputs["Detail"].default_value = rng.uniform(0, 8)
        t.inputs["Scale"].default_value = 1.0
        info["wave"] = t.wave_type
    else:  # magic
        t = nt.nodes.new("ShaderNodeTexMagic")
        t.turbulence_depth = rng.randint(2, 5)
        t.inputs["Scale"].default_value = 1.0
    link(nt, mapping.outputs["Vector"], t.inputs["Vector"])
    for cname in ("Color1", "Color2"):
        if cname in t.inputs:
            t.inputs[cname].default_value = (*rand_color(rng), 1)
    fac = t.outputs["Fac"] if "Fac" in t.outputs else t.outputs["Distance"]
    # colour through a two-colour ramp (hard or soft), except checker/brick which have colours
    if kind in ("checker", "brick"):
        col = t.outputs["Color"]
    else:
        ramp = nt.nodes.new("ShaderNodeValToRGB")
        ramp.color_ramp.interpolation = rng.choice(["LINEAR", "CONSTANT", "EASE"])
        ramp.color_ramp.elements[0].color = (*rand_color(rng, val=(0.02, 0.5)), 1)
        ramp.color_ramp.elements[1].color = (*rand_color(rng, val=(0.4, 0.95)), 1)
        ramp.color_ramp.elements[1].position = rng.uniform(0.3, 0.8)
        link(nt, fac, ramp.inputs["Fac"])
        col = ramp.outputs["Color"]
    return col, fac, info


def add_bump(nt, p, rng, scale=None, kind=None):
    kind = kind or rng.choice(TEXTURES)
    scale = scale or math.exp(rng.uniform(math.log(2), math.log(60)))
    _, fac, info = texture_node(nt, rng, kind, scale)
    bump = nt.nodes.new("ShaderNodeBump")
    bump.inputs["Strength"].default_value = rng.uniform(0.2, 1.0)
    bump.inputs["Distance"].default_value = rng.uniform(0.005, 0.05)
    link(nt, fac, bump.inputs["Height"])
    link(nt, bump.outputs["Normal"], p.inputs["Normal"])
    info["bump_strength"] = round(bump.inputs["Strength"].default_value, 3)
    return info


METAL_COLORS = {
    "gold": (1.0, 0.766, 0.336), "silver": (0.972, 0.960, 0.915), "copper": (0.955, 0.637, 0.538),
    "aluminium": (0.913, 0.922, 0.924), "iron": (0.56, 0.57, 0.58), "chrome": (0.55, 0.556, 0.554),
}


def make_material(rng, kind, name="mat"):
    """kind: diffuse, plastic, textured, bumped, metal, glass, emissive, coated."""
    m, nt, p = new_material(name)
    info = {"kind": kind}
    if kind == "diffuse":
        set_p(p, base=rand_color(rng), rough=rng.uniform(0.5, 1.0), spec=rng.uniform(0.0, 0.5))
    elif kind == "plastic":
        set_p(p, base=rand_color(rng), rough=rng.uniform(0.05, 0.4), spec=0.5)
    elif kind == "coated":
        set_p(p, base=rand_color(rng), rough=0.6, coat=1.0, coat_rough=rng.uniform(0.0, 0.1))
    elif kind == "textured":
        scale = math.exp(rng.uniform(math.log(1.5), math.log(60)))
        col, fac, tinfo = texture_node(nt, rng, rng.choice(TEXTURES), scale)
        if rng.random() < 0.3:  # multiply two textures
            col2, _, t2 = texture_node(nt, rng, rng.choice(TEXTURES),
                                       math.exp(rng.uniform(math.log(1.5), math.log(60))))
            mix = nt.nodes.new("ShaderNodeMixRGB")
            mix.blend_type = "MULTIPLY"
            mix.inputs["Fac"].default_value = 1.0
            link(nt, col, mix.inputs["Color1"])
            link(nt, col2, mix.inputs["Color2"])
            col = mix.outputs["Color"]
            tinfo["second"] = t2
        link(nt, col, p.inputs["Base Color"])
        set_p(p, rough=rng.uniform(0.2, 1.0), spec=rng.uniform(0.1, 0.6))
        if rng.random() < 0.3:  # glossy coat over texture
            set_p(p, coat=rng.uniform(0.1, 1.0), coat_rough=rng.uniform(0.0, 0.2))
        info.update(tinfo)
    elif kind == "bumped":
        if rng.random() < 0.5:
            col, _, tinfo = texture_node(nt, rng, rng.choice(TEXTURES),
                                         math.exp(rng.uniform(math.log(1.5), math.log(30))))
            link(nt, col, p.inputs["Base Color"])
            info["albedo"] = tinfo
        else:
            set_p(p, base=rand_color(rng))
        metal = rng.random() < 0.3
        set_p(p, rough=rng.uniform(0.05, 0.7), metallic=1.0 if metal else 0.0)
        info["bump"] = add_bump(nt, p, rng)
    elif kind == "metal":
        cname = rng.choice(list(METAL_COLORS) + ["tinted"])
        base = METAL_COLORS.get(cname) or rand_color(rng, sat=(0.3, 0.8), val=(0.6, 1.0))
        rough = rng.choice([rng.uniform(0.0, 0.05), rng.uniform(0.05, 0.25), rng.uniform(0.25, 0.6)])
        set_p(p, base=base, metallic=1.0, rough=rough)
        if rng.random() < 0.25:
            set_p(p, aniso=rng.uniform(0.3, 0.9), aniso_rot=rng.random())
        if rng.random() < 0.2:  # brushed / hammered
            info["bump"] = add_bump(nt, p, rng)
        info.update({"metal": cname, "roughness": round(rough, 3)})
    elif kind == "glass":
        rough = rng.choice([0.0, 0.0, 0.0, rng.uniform(0.02, 0.2)])
        tint = (1, 1, 1) if rng.random() < 0.5 else rand_color(rng, sat=(0.1, 0.6), val=(0.8, 1.0))
        set_p(p, base=tint, transmission=1.0, rough=rough, ior=rng.uniform(1.33, 1.7), spec=0.5)
        info.update({"roughness": round(rough, 3)})
    elif kind == "emissive":
        strength = math.exp(rng.uniform(math.log(10), math.log(400)))
        col = rand_color(rng, sat=(0.0, 0.8), val=(0.8, 1.0))
        set_p(p, base=(0.05, 0.05, 0.05), emission=col, estrength=strength)
        info["strength"] = round(strength, 2)
    return m, info


def assign(ob, mat):
    ob.data.materials.clear()
    ob.data.materials.append(mat)


def add_prim(kind, loc, scale=(1, 1, 1), rot=(0, 0, 0), mat=None):
    ops = bpy.ops.mesh
    if kind == "sphere":
        ops.primitive_uv_sphere_add(segments=64, ring_count=32, location=loc)
    elif kind == "ico":
        ops.primitive_ico_sphere_add(subdivisions=1, location=loc)
    elif kind == "cube":
        ops.primitive_cube_add(size=2.0, location=loc)
    elif kind == "cylinder":
        ops.primitive_cylinder_add(vertices=64, location=loc)
    elif kind == "cone":
        ops.primitive_cone_add(vertices=64, location=loc)
    elif kind == "torus":
        ops.primitive_torus_add(major_segments=72, minor_segments=24, location=loc)
    elif kind == "monkey":
        ops.primitive_monkey_add(location=loc)
    elif kind == "plane":
        ops.primitive_plane_add(size=2.0, location=loc)
    else:
        raise ValueError(kind)
    ob = bpy.context.active_object
    ob.scale = scale
    ob.rotation_euler = rot
    if kind in ("sphere", "torus", "monkey", "cylinder", "cone"):
        for poly in ob.data.polygons:
            poly.use_smooth = True
        ob.data.use_auto_smooth = True
        ob.data.auto_smooth_angle = math.radians(50)
    if kind == "monkey":
        ob.modifiers.new("sub", "SUBSURF").levels = 1
    if kind == "cube":
        bev = ob.modifiers.new("bevel", "BEVEL")
        bev.width = 0.03
        bev.segments = 3
        bev.limit_method = "NONE"
        ob.data.use_auto_smooth = True
        ob.data.auto_smooth_angle = math.radians(40)
        for poly in ob.data.polygons:
            poly.use_smooth = True
    if mat is not None:
        assign(ob, mat)
    return ob


def mesh_object(name, verts, faces, mat=None, smooth=False):
    me = bpy.data.meshes.new(name)
    me.from_pydata([tuple(v) for v in np.asarray(verts, dtype=float)], [],
                   [tuple(int(i) for i in f) for f in faces])
    me.update()
    if smooth:
        for poly in me.polygons:
            poly.use_smooth = True
    ob = bpy.data.objects.new(name, me)
    bpy.context.scene.collection.objects.link(ob)
    if mat is not None:
        me.materials.append(mat)
    return ob


def quad(name, center, size, rot, mat):
    ob = add_prim("plane", center, (size[0] / 2, size[1] / 2, 1), rot, mat)
    ob.name = name
    return ob


def area_light(loc, target, size, energy, color=(1, 1, 1), shape="RECTANGLE", size_y=None):
    ld = bpy.data.lights.new("area", "AREA")
    ld.shape = shape
    ld.size = size
    if size_y is not None and shape == "RECTANGLE":
        ld.size_y = size_y
    ld.energy = energy
    ld.color = color
    ob = bpy.data.objects.new("area", ld)
    bpy.context.scene.collection.objects.link(ob)
    ob.location = loc
    look_at(ob, target)
    return ob


def look_at(ob, target):
    d = Vector(target) - Vector(ob.location)
    ob.rotation_euler = d.to_track_quat("-Z", "Y").to_euler()


def world_color(color, strength):
    w = bpy.data.worlds.new("world")
    w.use_nodes = True
    bg = w.node_tree.nodes["Background"]
    bg.inputs["Color"].default_value = (*color, 1)
    bg.inputs["Strength"].default_value = strength
    bpy.context.scene.world = w
    return {"world": "constant", "strength": round(strength, 4)}


def sun_and_sky(rng, elevation=None):
    """Physical sky (Nishita or Hosek-Wilkie) plus a matching sun lamp."""
    elev = elevation if elevation is not None else rng.uniform(8, 65)
    azim = rng.uniform(0, 360)
    w = bpy.data.worlds.new("sky")
    w.use_nodes = True
    nt = w.node_tree
    sky = nt.nodes.new("ShaderNodeTexSky")
    sky_type = rng.choice(["NISHITA", "NISHITA", "HOSEK_WILKIE"])
    sky.sky_type = sky_type
    if sky_type == "NISHITA":
        sky.sun_disc = False
        sky.sun_elevation = math.radians(elev)
        sky.sun_rotation = math.radians(azim)
        sky.air_density = rng.uniform(0.5, 2.5)
        sky.dust_density = rng.uniform(0.0, 3.0)
        sky_strength = rng.uniform(0.15, 0.5)
    else:
        d = Vector((math.cos(math.radians(elev)) * math.cos(math.radians(azim)),
                    math.cos(math.radians(elev)) * math.sin(math.radians(azim)),
                    math.sin(math.radians(elev))))
        sky.sun_direction = d
        sky.turbidity = rng.uniform(2, 6)
        sky_strength = rng.uniform(0.05, 0.15)
    bg = nt.nodes["Background"]
    bg.inputs["Strength"].default_value = sky_strength
    link(nt, sky.outputs["Color"], bg.inputs["Color"])
    bpy.context.scene.world = w
    ld = bpy.data.lights.new("sun", "SUN")
    ld.energy = rng.uniform(2.0, 6.0)
    ld.angle = math.radians(rng.uniform(0.5, 3.0))
    ld.color = (1.0, rng.uniform(0.85, 1.0), rng.uniform(0.7, 0.95))
    ob = bpy.data.objects.new("sun", ld)
    bpy.context.scene.collection.objects.link(ob)
    e, a = math.radians(elev), math.radians(azim)
    ob.location = (math.cos(e) * math.cos(a) * 50, math.cos(e) * math.sin(a) * 50, math.sin(e) * 50)
    look_at(ob, (0, 0, 0))
    return {"world": "sky", "sky_type": sky_type, "sun_elevation": round(elev, 2),
            "sun_azimuth": round(azim, 2), "sun_strength": round(ld.energy, 3),
            "sky_strength": round(sky_strength, 3)}


# ----------------------------------------------------------------------------------------
# stages: the overall layout, lights and the bounding region for content and camera
# ----------------------------------------------------------------------------------------
class Stage:
    def __init__(self, name):
        self.name = name
        self.info = {"stage": name}
        self.content_box = ((-1, -1), (1, 1))  # xy region for content, floor at z=0
        self.cam_box = ((-3, -3, 0.3), (3, 3, 2))  # camera position region
        self.scale = 1.0  # typical object size


def floor_material(rng, family):
    r = rng.random()
    if family == "bump" or (r < 0.2):
        return make_material(rng, "bumped", "floor")
    if family in ("texture", "dof", "glass") or r < 0.6:
        return make_material(rng, "textured", "floor")
    if r < 0.8:
        return make_material(rng, "coated", "floor")
    return make_material(rng, "diffuse", "floor")


def wall_material(rng, family):
    if family == "texture" and rng.random() < 0.5:
        return make_material(rng, "textured", "wall")
    if family == "bump" and rng.random() < 0.5:
        return make_material(rng, "bumped", "wall")
    m, nt, p = new_material("wall")
    c = rand_color(rng, sat=(0.0, 0.4), val=(0.4, 0.9))
    set_p(p, base=c, rough=0.9, spec=0.2)
    return m, {"kind": "wall", "color": [round(x, 3) for x in c]}


def room_shell(rng, family, w, d, h, window=None):
    fm, finfo = floor_material(rng, family)
    wm, winfo = wall_material(rng, family)
    cm, _ = make_material(rng, "diffuse", "ceiling")
    set_p(cm.node_tree.nodes["Principled BSDF"], base=(0.8, 0.8, 0.8))
    quad("floor", (0, 0, 0), (w, d), (0, 0, 0), fm)
    quad("ceiling", (0, 0, h), (w, d), (math.pi, 0, 0), cm)
    quad("wall_n", (0, d / 2, h / 2), (w, h), (math.pi / 2, 0, 0), wm)
    quad("wall_e", (w / 2, 0, h / 2), (d, h), (math.pi / 2, 0, math.pi / 2), wm)
    quad("wall_w", (-w / 2, 0, h / 2), (d, h), (math.pi / 2, 0, -math.pi / 2), wm)
    if window is None:
        quad("wall_s", (0, -d / 2, h / 2), (w, h), (math.pi / 2, 0, math.pi), wm)
    else:  # south wall with a window opening: four pieces around the hole
        wx0, wx1, wz0, wz1 = window
        y = -d / 2
        rot = (math.pi / 2, 0, math.pi)
        quad("wall_s_l", ((-w / 2 + wx0) / 2, y, h / 2), (wx0 + w / 2, h), rot, wm)
        quad("wall_s_r", ((w / 2 + wx1) / 2, y, h / 2), (w / 2 - wx1, h), rot, wm)
        quad("wall_s_b", ((wx0 + wx1) / 2, y, wz0 / 2), (wx1 - wx0, wz0), rot, wm)
        quad("wall_s_t", ((wx0 + wx1) / 2, y, (wz1 + h) / 2), (wx1 - wx0, h - wz1), rot, wm)
    return {"floor": finfo, "wall": winfo, "size": [round(w, 2), round(d, 2), round(h, 2)]}


def stage_room(rng, family):
    st = Stage("room")
    w, d, h = rng.uniform(3, 7), rng.uniform(3, 7), rng.uniform(2.4, 3.5)
    st.info["shell"] = room_shell(rng, family, w, d, h)
    n = rng.randint(1, 3)
    lights = []
    for i in range(n):
        x, y = rng.uniform(-w / 3, w / 3), rng.uniform(-d / 3, d / 3)
        s = rng.uniform(0.4, 1.5)
        e = rng.uniform(150, 600) * (w * d / 20)
        area_light((x, y, h - 0.01), (x, y, 0), s, e / n, color=(1, rng.uniform(0.85, 1), rng.uniform(0.7, 1)))
        lights.append({"size": round(s, 2), "energy": round(e / n, 1)})
    world_color((0.05, 0.05, 0.05), 0.0)
    st.info["lights"] = lights
    st.content_box = ((-w / 2 + 0.6, -d / 2 + 0.6), (w / 2 - 0.6, d / 2 - 0.6))
    st.cam_box = ((-w / 2 + 0.2, -d / 2 + 0.2, 0.4), (w / 2 - 0.2, d / 2 - 0.2, h - 0.4))
    st.scale = 0.35
    return st


def stage_corridor(rng, family):
    st = Stage("corridor")
    w, d, h = rng.uniform(1.8, 3.0), rng.uniform(10, 18), rng.uniform(2.4, 3.2)
    st.info["shell"] = room_shell(rng, family, w, d, h)
    n = rng.randint(3, 6)
    for i in range(n):
        y = -d / 2 + (i + 0.5) * d / n
        area_light((0, y, h - 0.01), (0, y, 0), rng.uniform(0.3, 0.8), rng.uniform(60, 250),
                   shape="RECTANGLE", size_y=rng.uniform(0.1, 0.5))
    # pillars along the walls
    pm, _ = make_material(rng, rng.choice(["diffuse", "plastic", "textured"]), "pillar")
    for i in range(n + 1):
        y = -d / 2 + i * d / n
        for sx in (-1, 1):
            add_prim("cube", (sx * (w / 2 - 0.1), y, h / 2), (0.12, 0.12, h / 2), mat=pm)
    world_color((0.05, 0.05, 0.05), 0.0)
    st.info["lights"] = n
    st.content_box = ((-w / 2 + 0.4, -d / 2 + 1), (w / 2 - 0.4, d / 2 - 1))
    st.cam_box = ((-w / 2 + 0.3, -d / 2 + 0.3, 0.4), (w / 2 - 0.3, -d / 4, h - 0.5))
    st.scale = 0.3
    return st


def stage_indirect_room(rng, family):
    """Room lit only indirectly: lights hidden behind a partition / pointed at the ceiling."""
    st = Stage("indirect_room")
    w, d, h = rng.uniform(4, 7), rng.uniform(4, 7), rng.uniform(2.6, 3.5)
    st.info["shell"] = room_shell(rng, family, w, d, h)
    wm, _ = wall_material(rng, family)
    # partition across the room at y = d/4 with a gap at the top
    add_prim("cube", (0, d / 4, (h - 0.6) / 2), (w / 2 - 0.05, 0.05, (h - 0.6) / 2), mat=wm)
    for i in range(rng.randint(1, 2)):
        x = rng.uniform(-w / 3, w / 3)
        area_light((x, d / 4 + 0.5, 0.3), (x, d / 4 + 0.5, h), rng.uniform(0.5, 1.5),
                   rng.uniform(400, 1500))
    world_color((0.05, 0.05, 0.05), 0.0)
    st.content_box = ((-w / 2 + 0.5, -d / 2 + 0.5), (w / 2 - 0.5, d / 4 - 0.4))
    st.cam_box = ((-w / 2 + 0.2, -d / 2 + 0.2, 0.4), (w / 2 - 0.2, 0, h - 0.4))
    st.scale = 0.35
    return st


def stage_window_room(rng, family):
    """Room lit by sun and sky through a window in the south wall."""
    st = Stage("window_room")
    w, d, h = rng.uniform(4, 7), rng.uniform(4, 7), rng.uniform(2.6, 3.4)
    ww = rng.uniform(1.0, min(2.5, w - 1))
    x0 = rng.uniform(-w / 2 + 0.4, w / 2 - 0.4 - ww)
    window = (x0, x0 + ww, rng.uniform(0.6, 1.0), rng.uniform(1.8, h - 0.3))
    st.info["shell"] = room_shell(rng, family, w, d, h, window=window)
    # sun from the south, low enough to come in through the window
    st.info["sky"] = sun_and_sky(rng, elevation=rng.uniform(12, 40))
    sun = bpy.data.objects["sun"]
    az = math.radians(rng.uniform(-120, -60))
    e = math.radians(st.info["sky"]["sun_elevation"])
    sun.location = (math.cos(e) * math.cos(az) * 50, math.cos(e) * math.sin(az) * 50, math.sin(e) * 50)
    look_at(sun, (0, 0, 0))
    sky = bpy.context.scene.world.node_tree.nodes["Sky Texture"]
    if sky.sky_type == "NISHITA":
        sky.sun_rotation = az
    else:
        sky.sun_direction = Vector(sun.location).normalized()
    st.info["sky"]["sun_azimuth"] = round(math.degrees(az), 2)
    if rng.random() < 0.5:
        area_light((0, 0, h - 0.01), (0, 0, 0), 0.5, rng.uniform(20, 100))
    st.content_box = ((-w / 2 + 0.5, -d / 2 + 0.8), (w / 2 - 0.5, d / 2 - 0.5))
    st.cam_box = ((-w / 2 + 0.2, -d / 2 + 0.2, 0.4), (w / 2 - 0.2, d / 2 - 0.2, h - 0.4))
    st.scale = 0.35
    return st


def stage_ground(rng, family):
    st = Stage("ground")
    fm, finfo = floor_material(rng, family)
    quad("ground", (0, 0, 0), (200, 200), (0, 0, 0), fm)
    st.info["sky"] = sun_and_sky(rng)
    st.info["floor"] = finfo
    st.content_box = ((-3, -3), (3, 3))
    st.cam_box = ((-8, -8, 0.3), (8, 8, 4))
    st.scale = 0.5
    return st


def stage_city(rng, family):
    st = Stage("city")
    fm, finfo = floor_material(rng, family)
    quad("ground", (0, 0, 0), (300, 300), (0, 0, 0), fm)
    st.info["sky"] = sun_and_sky(rng, elevation=rng.uniform(5, 35))
    mats = [make_material(rng, rng.choice(["diffuse", "textured", "coated", "bumped"]), "bldg")[0]
            for _ in range(4)]
    glassm, _ = make_material(rng, "metal", "window")
    n = rng.randint(4, 7)
    pitch = rng.uniform(6, 12)
    for i in range(-n, n + 1):
        for j in range(-n, n + 1):
            if i == 0 and j == 0:
                continue  # a plaza in the middle for the content
            if rng.random() < 0.15:
                continue
            hgt = math.exp(rng.uniform(math.log(3), math.log(40)))
            bw = pitch * rng.uniform(0.5, 0.8)
            add_prim("cube", (i * pitch, j * pitch, hgt / 2), (bw / 2, bw / 2, hgt / 2),
                     mat=rng.choice(mats + [glassm]))
    st.info["blocks"] = n
    st.content_box = ((-pitch / 3, -pitch / 3), (pitch / 3, pitch / 3))
    st.cam_box = ((-pitch / 2, -pitch / 2, 0.5), (pitch / 2, pitch / 2, 6))
    st.scale = 0.6
    return st


def stage_terrain(rng, family):
    st = Stage("terrain")
    n = 160
    size = 60.0
    xs = np.linspace(-size / 2, size / 2, n)
    X, Y = np.meshgrid(xs, xs)
    Z = np.zeros_like(X)
    amp = rng.uniform(0.3, 2.0)
    for k in range(6):
        f = (0.05 + 0.08 * rng.random()) * (2 ** k)
        ph = rng.uniform(0, 6.3)
        ang = rng.uniform(0, 6.3)
        Z += amp / (2 ** k) * np.sin(f * (X * math.cos(ang) + Y * math.sin(ang)) + ph)
    Z -= Z[n // 2, n // 2]
    r = np.sqrt(X ** 2 + Y ** 2)
    Z *= np.clip(r / 4.0, 0.0, 1.0)  # flat-ish centre for content
    verts = np.stack([X.ravel(), Y.ravel(), Z.ravel()], axis=1)
    idx = np.arange(n * n).reshape(n, n)
    faces = np.stack([idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(),
                      idx[1:, :-1].ravel()], axis=1)
    fm, finfo = floor_material(rng, family)
    mesh_object("terrain", verts, faces, fm, smooth=True)
    st.info["sky"] = sun_and_sky(rng)
    st.info["floor"] = finfo
    st.info["amplitude"] = round(amp, 3)
    # rocks
    rm, _ = make_material(rng, rng.choice(["bumped", "diffuse", "textured"]), "rock")
    for i in range(rng.randint(5, 20)):
        a, rr = rng.uniform(0, 6.3), rng.uniform(4, 20)
        s = rng.uniform(0.2, 1.5)
        ob = add_prim("ico", (rr * math.cos(a), rr * math.sin(a), 0), (s, s * rng.uniform(0.6, 1.4), s * 0.6),
                      (rng.random(), rng.random(), rng.random()), rm)
    st.content_box = ((-2.5, -2.5), (2.5, 2.5))
    st.cam_box = ((-7, -7, 0.8), (7, 7, 4))
    st.scale = 0.5
    return st


def stage_colonnade(rng, family):
    st = Stage("colonnade")
    fm, finfo = floor_material(rng, family)
    quad("ground", (0, 0, 0), (200, 200), (0, 0, 0), fm)
    st.info["sky"] = sun_and_sky(rng, elevation=rng.uniform(20, 70))
    pm, _ = make_material(rng, rng.choice(["diffuse", "textured", "bumped", "coated"]), "stone")
    h = rng.uniform(3, 5)
    span = rng.uniform(6, 10)
    nb = rng.randint(6, 14)
    for i in range(nb + 1):
        x = -span / 2 + i * span / nb
        for y in (-2.5, 2.5):
            add_prim("cylinder", (x, y, h / 2), (0.18, 0.18, h / 2), mat=pm)
    # pergola beams casting striped shadows
    nbeam = rng.randint(8, 24)
    for i in range(nbeam):
        x = -span / 2 + (i + 0.5) * span / nbeam
        add_prim("cube", (x, 0, h + 0.1), (0.05, 2.8, 0.1), mat=pm)
    for y in (-2.5, 2.5):
        add_prim("cube", (0, y, h), (span / 2 + 0.2, 0.15, 0.12), mat=pm)
    st.content_box = ((-span / 3, -1.8), (span / 3, 1.8))
    st.cam_box = ((-span / 2, -2.2, 0.4), (span / 2, 2.2, 2.5))
    st.scale = 0.4
    return st


def stage_studio(rng, family):
    """Cyclorama backdrop with softboxes."""
    st = Stage("studio")
    fm, finfo = floor_material(rng, family) if rng.random() < 0.5 else make_material(rng, "diffuse", "cyc")
    R, width, n = 2.0, 14.0, 24
    verts, faces = [], []
    prof = [(y, 0.0) for y in np.linspace(-8, 0, 6)[:-1]]
    prof += [(R * math.sin(t), R - R * math.cos(t)) for t in np.linspace(0, math.pi / 2, n)]
    prof += [(R, z) for z in np.linspace(R, 8, 5)[1:]]
    for (y, z) in prof:
        verts.append((-width / 2, y + 3, z))
        verts.append((width / 2, y + 3, z))
    for i in range(len(prof) - 1):
        faces.append((2 * i, 2 * i + 1, 2 * i + 3, 2 * i + 2))
    mesh_object("cyc", verts, faces, fm, smooth=True)
    for i in range(rng.randint(2, 4)):
        a = rng.uniform(-2.5, 0.5)
        loc = (4 * math.sin(a), -4 * math.cos(a) + 1, rng.uniform(1.5, 4))
        area_light(loc, (0, 1, 0.5), rng.uniform(0.5, 2.5), rng.uniform(100, 800),
                   color=(1, rng.uniform(0.8, 1), rng.uniform(0.6, 1)))
    world_color(rand_color(rng, val=(0.3, 1.0)), rng.uniform(0.0, 0.3))
    st.info["floor"] = finfo
    st.content_box = ((-1.5, -1.0), (1.5, 2.5))
    st.cam_box = ((-3.5, -5, 0.3), (3.5, -1.5, 3))
    st.scale = 0.35
    return st


STAGES = {
    "room": stage_room, "corridor": stage_corridor, "indirect_room": stage_indirect_room,
    "window_room": stage_window_room, "ground": stage_ground, "city": stage_city,
    "terrain": stage_terrain, "colonnade": stage_colonnade, "studio": stage_studio,
}

FAMILY_STAGES = {
    "interior": ["room", "corridor", "indirect_room", "window_room"],
    "exterior": ["ground", "city", "terrain", "colonnade"],
    "texture": ["room", "ground", "studio", "corridor", "terrain"],
    "bump": ["room", "ground", "studio", "colonnade", "indirect_room"],
    "metal": ["room", "studio", "ground", "city", "window_room"],
    "glass": ["studio", "room", "ground", "window_room"],
    "emissive": ["room", "ground", "studio", "corridor"],
    "fine": ["ground", "terrain", "studio", "room"],
    "dof": ["room", "ground", "studio", "corridor", "colonnade"],
}

FAMILY_MATERIALS = {
    "interior": {"diffuse": 3, "textured": 2, "plastic": 2, "metal": 1, "coated": 1, "glass": 0.5},
    "exterior": {"diffuse": 3, "textured": 2, "bumped": 1, "metal": 1, "coated": 1},
    "texture": {"textured": 8, "diffuse": 1},
    "bump": {"bumped": 8, "textured": 1},
    "metal": {"metal": 8, "plastic": 1, "textured": 1},
    "glass": {"glass": 7, "diffuse": 1, "textured": 1, "metal": 1},
    "emissive": {"diffuse": 2, "plastic": 2, "metal": 2, "textured": 1, "glass": 1},
    "fine": {"diffuse": 2, "textured": 1, "metal": 1},
    "dof": {"textured": 3, "diffuse": 2, "metal": 2, "plastic": 1, "glass": 1},
}


def weighted(rng, table):
    keys = list(table)
    return rng.choices(keys, weights=[table[k] for k in keys])[0]


# ----------------------------------------------------------------------------------------
# content
# ----------------------------------------------------------------------------------------
PRIMS = ["sphere", "cube", "cylinder", "cone", "torus", "monkey", "ico"]


def place_content(rng, st, family, n):
    (x0, y0), (x1, y1) = st.content_box
    arrangement = rng.choice(["cluster", "row", "grid", "pile"])
    objs = []
    s0 = st.scale
    cx, cy = rng.uniform(x0, x1), rng.uniform(y0, y1)
    for i in range(n):
        s = s0 * math.exp(rng.uniform(-0.6, 0.5))
        if arrangement == "cluster":
            x, y = cx + rng.gauss(0, 3 * s0), cy + rng.gauss(0, 3 * s0)
        elif arrangement == "row":
            t = (i + 0.5) / n
            x, y = x0 + (x1 - x0) * t, cy + rng.gauss(0, 0.3 * s0)
        elif arrangement == "grid":
            k = max(1, int(math.ceil(math.sqrt(n))))
            x = x0 + (x1 - x0) * ((i % k) + 0.5) / k
            y = y0 + (y1 - y0) * ((i // k) + 0.5) / k
        else:  # pile: stacked on top of each other around a centre
            x, y = cx + rng.gauss(0, 1.2 * s0), cy + rng.gauss(0, 1.2 * s0)
        x, y = min(max(x, x0), x1), min(max(y, y0), y1)
        z = s
        if arrangement == "pile":
            z = s + sum(1 for o in objs if (Vector(o["loc"][:2]) - Vector((x, y))).length < 2 * s0) * 1.5 * s0
        kind = rng.choice(PRIMS)
        objs.append({"prim": kind, "loc": (x, y, z), "size": s})
    return arrangement, objs


def build_objects(rng, objs, family):
    made = []
    mats_info = []
    for o in objs:
        mk = weighted(rng, FAMILY_MATERIALS[family])
        mat, minfo = make_material(rng, mk, "obj")
        mats_info.append(minfo)
        s = o["size"]
        kind = o["prim"]
        rot = (0, 0, rng.uniform(0, 6.3))
        scale = (s, s, s)
        if kind == "cube":
            scale = (s * rng.uniform(0.5, 1.2), s * rng.uniform(0.5, 1.2), s * rng.uniform(0.5, 1.2))
        if kind == "torus":
            rot = (rng.uniform(0, 1.6), 0, rng.uniform(0, 6.3))
        if kind == "cylinder":
            scale = (s * 0.6, s * 0.6, s)
        loc = (o["loc"][0], o["loc"][1], o["loc"][2] if kind != "torus" else o["loc"][2] * 0.6)
        ob = add_prim(kind, loc, scale, rot, mat)
        made.append(ob)
    return made, mats_info


def add_emitters(rng, st, n):
    (x0, y0), (x1, y1) = st.content_box
    info = []
    for i in range(n):
        mat, minfo = make_material(rng, "emissive", "emit")
        s = st.scale * rng.uniform(0.03, 0.25)
        kind = rng.choice(["sphere", "sphere", "cube", "cylinder", "torus"])
        loc = (rng.uniform(x0, x1), rng.uniform(y0, y1), rng.uniform(s, 6 * st.scale))
        ob = add_prim(kind, loc, (s, s, s * (4 if kind == "cylinder" else 1)),
                      (rng.uniform(0, 3), rng.uniform(0, 3), 0), mat)
        minfo["size"] = round(s, 3)
        minfo["loc"] = [round(v, 3) for v in loc]
        info.append(minfo)
    return info


def add_grass(rng, st, center, radius, n):
    """Thousands of thin, bent, tapered grass blades as one mesh."""
    verts, faces = [], []
    h0 = st.scale * rng.uniform(0.3, 1.0)
    wid = h0 * rng.uniform(0.01, 0.04)
    seg = 4
    for b in range(n):
        r = radius * math.sqrt(rng.random())
        a = rng.uniform(0, 6.283)
        bx, by = center[0] + r * math.cos(a), center[1] + r * math.sin(a)
        h = h0 * rng.uniform(0.5, 1.5)
        yaw = rng.uniform(0, 6.283)
        lean = rng.uniform(0, 0.8)
        lx, ly = math.cos(yaw), math.sin(yaw)
        px, py = -ly, lx
        base = len(verts)
        for k in range(seg + 1):
            t = k / seg
            off = lean * h * t * t
            cx, cy, cz = bx + lx * off, by + ly * off, h * t * (1 - 0.3 * lean * t)
            ww = wid * (1 - t) + 1e-4
            verts.append((cx - px * ww, cy - py * ww, cz))
            verts.append((cx + px * ww, cy + py * ww, cz))
        for k in range(seg):
            i = base + 2 * k
            faces.append((i, i + 1, i + 3, i + 2))
    m, nt, p = new_material("grass")
    set_p(p, base=rand_color(rng, sat=(0.4, 0.9), val=(0.1, 0.5)), rough=rng.uniform(0.3, 0.8),
          spec=0.4)
    p.inputs["Subsurface"].default_value = 0.0
    ob = mesh_object("grass", verts, faces, m)
    return {"grass_blades": n, "blade_height": round(h0, 3), "blade_width": round(wid, 4)}


def add_wires(rng, st, center):
    """A fence / lattice of thin cylinders (prisms), one mesh."""
    verts, faces = [], []
    r = st.scale * rng.uniform(0.003, 0.015)
    sides = 6

    def cyl(p0, p1):
        p0, p1 = Vector(p0), Vector(p1)
        d = (p1 - p0).normalized()
        u = d.orthogonal().normalized()
        v = d.cross(u)
        base = len(verts)
        for p in (p0, p1):
            for k in range(sides):
                a = 2 * math.pi * k / sides
                q = p + r * (math.cos(a) * u + math.sin(a) * v)
                verts.append(tuple(q))
        for k in range(sides):
            k1 = (k + 1) % sides
            faces.append((base + k, base + k1, base + sides + k1, base + sides + k))

    size = st.scale * rng.uniform(3, 6)
    n = rng.randint(10, 40)
    yaw = rng.uniform(0, 6.3)
    ax, ay = math.cos(yaw), math.sin(yaw)
    cx, cy = center
    kind = rng.choice(["fence", "lattice", "strands"])
    if kind == "fence":
        for i in range(n + 1):
            t = -size / 2 + size * i / n
            cyl((cx + ax * t, cy + ay * t, 0), (cx + ax * t, cy + ay * t, size * 0.6))
            cyl((cx + ax * t - ay * 0.01, cy + ay * t + ax * 0.01, 0), (cx + ax * (t + size / n), cy + ay * (t + size / n), size * 0.6))
        for j in range(n // 2):
            z = size * 0.6 * (j + 0.5) / (n // 2)
            cyl((cx - ax * size / 2, cy - ay * size / 2, z), (cx + ax * size / 2, cy + ay * size / 2, z))
    elif kind == "lattice":
        for i in range(n + 1):
            for j in range(3):
                t = -size / 2 + size * i / n
                h = size * 0.2 * (j + 1)
                cyl((cx + ax * t - ay * size / 2, cy + ay * t + ax * size / 2, h),
                    (cx + ax * t + ay * size / 2, cy + ay * t - ax * size / 2, h))
                cyl((cx - ax * size / 2 - ay * t, cy - ay * size / 2 + ax * t, h + 0.02),
                    (cx + ax * size / 2 - ay * t, cy + ay * size / 2 + ax * t, h + 0.02))
    else:  # hanging strands
        for i in range(n * 8):
            x, y = cx + rng.uniform(-size / 2, size / 2), cy + rng.uniform(-size / 4, size / 4)
            top = size * 0.8
            cyl((x, y, top), (x + rng.gauss(0, 0.02 * size), y + rng.gauss(0, 0.02 * size), top * rng.uniform(0.1, 0.8)))
    mat, minfo = make_material(rng, rng.choice(["metal", "diffuse", "plastic"]), "wire")
    mesh_object("wires", verts, faces, mat)
    return {"wires": kind, "radius": round(r, 4), "count": len(faces) // sides, "material": minfo}


def add_fur(rng, ob, st):
    """Particle hair on an object: hair-like thin curve primitives."""
    mod = ob.modifiers.new("fur", "PARTICLE_SYSTEM")
    ps = ob.particle_systems[-1].settings
    ps.type = "HAIR"
    ps.count = rng.randint(1500, 6000)
    ps.hair_length = st.scale * rng.uniform(0.15, 0.6)
    ps.child_type = "INTERPOLATED"
    ps.rendered_child_count = rng.randint(3, 10)
    ps.display_step = 3
    ps.render_step = 3
    ps.root_radius = 1.0
    ps.tip_radius = 0.0
    ps.radius_scale = st.scale * rng.uniform(0.004, 0.015)
    ps.roughness_2 = rng.uniform(0.0, 0.3)
    ps.use_advanced_hair = False
    ps.kink = rng.choice(["NO", "CURL", "WAVE"])
    m, nt, p = new_material("fur")
    set_p(p, base=rand_color(rng), rough=rng.uniform(0.2, 0.6))
    ob.data.materials.append(m)
    ps.material = len(ob.data.materials)
    return {"hair_count": ps.count, "children": ps.rendered_child_count,
            "hair_length": round(ps.hair_length, 3)}


# ----------------------------------------------------------------------------------------
# camera
# ----------------------------------------------------------------------------------------
def setup_camera(rng, st, targets, family):
    cam_data = bpy.data.cameras.new("cam")
    cam = bpy.data.objects.new("cam", cam_data)
    bpy.context.scene.collection.objects.link(cam)
    bpy.context.scene.camera = cam
    tgt = Vector(rng.choice(targets)) if targets else Vector((0, 0, st.scale))
    (a0, b0, c0), (a1, b1, c1) = st.cam_box
    best = None
    for attempt in range(30):
        p = Vector((rng.uniform(a0, a1), rng.uniform(b0, b1), rng.uniform(c0, c1)))
        dist = (p - tgt).length
        if 3 * st.scale < dist < 30 * st.scale:
            best = p
            break
    if best is None:
        best = tgt + Vector((0, -6 * st.scale, 2 * st.scale))
    cam.location = best
    look_at(cam, tgt + Vector((rng.gauss(0, 0.3 * st.scale), rng.gauss(0, 0.3 * st.scale), 0)))
    cam.rotation_euler.rotate_axis("Z", rng.gauss(0, 0.08))  # slight roll
    cam_data.lens = math.exp(rng.uniform(math.log(24), math.log(85)))
    cam_data.clip_start = 0.01
    cam_data.clip_end = 1000
    info = {"location": [round(x, 3) for x in cam.location], "target": [round(x, 3) for x in tgt],
            "lens_mm": round(cam_data.lens, 2)}
    if family == "dof":
        cam_data.dof.use_dof = True
        cam_data.dof.focus_distance = (cam.location - tgt).length * rng.uniform(0.7, 1.1)
        cam_data.dof.aperture_fstop = math.exp(rng.uniform(math.log(0.5), math.log(4.0)))
        cam_data.dof.aperture_blades = rng.choice([0, 0, 5, 6, 8])
        info.update({"dof": True, "focus_distance": round(cam_data.dof.focus_distance, 3),
                     "fstop": round(cam_data.dof.aperture_fstop, 3)})
    return cam, info


def level_camera(sky, aspect):
    """Turn the camera about its own horizontal axis, keeping its heading and dropping the
    roll, so that the horizon lies `sky` of the frame's height below its top (the sky fills
    what the content does not hide above it); aspect is height / width."""
    cam = bpy.context.scene.camera
    d = cam.rotation_euler.to_matrix() @ Vector((0, 0, -1))
    heading = math.atan2(d.y, d.x)
    # Blender fits the sensor to the wider side: the vertical half-angle's tangent
    half_v = (cam.data.sensor_width / 2 / cam.data.lens) * min(aspect, 1.0)
    pitch = math.atan((2 * sky - 1) * half_v)  # above the horizontal: horizon moves down
    cam.rotation_euler = (math.pi / 2 + pitch, 0.0, heading - math.pi / 2)
    return {"sky": sky, "pitch_deg": round(math.degrees(pitch), 3)}


def build_caustics(rng, seed):
    """Sun through clear glass and off mirrors onto a diffuse ground and wall, all in view:
    caustics seen directly and through the glass, whose light arrives on a few paths per
    pixel (heavy-tailed noise). The camera looks at where the first sphere's caustic lands."""
    clear_scene()
    info = {"family": "caustics", "seed": seed, "stage": {"stage": "caustic_court"}}
    gm, ginfo = make_material(rng, rng.choice(["textured", "textured", "diffuse", "bumped"]), "ground")
    quad("ground", (0, 0, 0), (200, 200), (0, 0, 0), gm)
    wm, winfo = make_material(rng, rng.choice(["textured", "bumped", "diffuse"]), "wall")
    wall_y = rng.uniform(1.5, 3.0)
    quad("wall", (0, wall_y, 2.0), (10.0, 4.0), (math.pi / 2, 0, 0), wm)
    # The sun behind the camera's side (-y), low enough that caustics stretch towards the wall.
    sky = sun_and_sky(rng, elevation=rng.uniform(25, 55))
    sun = bpy.data.objects["sun"]
    elev = math.radians(sky["sun_elevation"])
    azim = math.radians(rng.uniform(-130, -50))
    sun.location = (math.cos(elev) * math.cos(azim) * 50, math.cos(elev) * math.sin(azim) * 50,
                    math.sin(elev) * 50)
    look_at(sun, (0, 0, 0))
    sun.data.angle = math.radians(rng.uniform(0.3, 1.0))
    sun.data.energy = rng.uniform(3.0, 8.0)
    world = bpy.context.scene.world.node_tree.nodes
    if "Sky Texture" in world and world["Sky Texture"].sky_type == "NISHITA":
        world["Sky Texture"].sun_rotation = azim
    info["stage"].update({"ground": ginfo, "wall": winfo, "wall_y": round(wall_y, 3), "sky": sky,
                          "sun_azimuth": round(math.degrees(azim), 2)})
    to_ground = -Vector(sun.location).normalized()  # the sunlight's direction
    objects, targets = [], []
    for i in range(rng.randint(1, 3)):  # clear glass spheres
        r = rng.uniform(0.25, 0.6)
        c = Vector((rng.uniform(-1.5, 1.5), rng.uniform(-1.0, wall_y - 1.2), r))
        m, nt, p = new_material("glass")
        ior = rng.uniform(1.4, 1.6)
        set_p(p, base=(1, 1, 1), transmission=1.0, rough=0.0, ior=ior, spec=0.5)
        CONTENT.append(add_prim("sphere", tuple(c), (r, r, r), mat=m).name)
        spot = c + to_ground * (c.z / -to_ground.z)  # where its focused light lands
        targets.append(((c + spot) / 2))
        objects.append({"prim": "sphere", "material": "clear glass", "ior": round(ior, 3),
                        "radius": round(r, 3), "loc": [round(v, 3) for v in c]})
    for i in range(rng.randint(1, 2)):  # mirror-like and rough metal: reflected caustics
        kind = rng.choice(["torus", "cylinder", "sphere"])
        s = rng.uniform(0.25, 0.5)
        rough = rng.choice([rng.uniform(0.0, 0.03), rng.uniform(0.15, 0.35)])
        m, nt, p = new_material("metal")
        set_p(p, base=rand_color(rng, sat=(0.0, 0.3), val=(0.8, 1.0)), metallic=1.0, rough=rough)
        loc = (rng.uniform(-2.0, 2.0), rng.uniform(-1.0, wall_y - 1.0), s)
        rot = (rng.uniform(0.3, 1.3), 0, rng.uniform(0, 6.3)) if kind == "torus" else (0, 0, 0)
        CONTENT.append(add_prim(kind, loc, (s, s, s), rot, m).name)
        objects.append({"prim": kind, "material": "metal", "roughness": round(rough, 3),
                        "size": round(s, 3), "loc": [round(v, 3) for v in loc]})
    info["objects"] = objects
    # Camera on the sun's side, looking at the first sphere's light on the ground.
    cam_data = bpy.data.cameras.new("cam")
    cam = bpy.data.objects.new("cam", cam_data)
    bpy.context.scene.collection.objects.link(cam)
    bpy.context.scene.camera = cam
    tgt = targets[0]
    cam.location = (tgt.x + rng.uniform(-2.0, 2.0), tgt.y - rng.uniform(3.0, 5.5), rng.uniform(0.6, 2.2))
    look_at(cam, tgt)
    cam_data.lens = rng.uniform(30, 60)
    cam_data.clip_start, cam_data.clip_end = 0.01, 1000
    info["camera"] = {"location": [round(v, 3) for v in cam.location],
                      "target": [round(v, 3) for v in tgt], "lens_mm": round(cam_data.lens, 2)}
    if rng.random() < 0.5:
        cam_data.dof.use_dof = True
        cam_data.dof.focus_distance = (Vector(cam.location) - tgt).length
        cam_data.dof.aperture_fstop = rng.uniform(2.0, 8.0)
        info["camera"]["dof_fstop"] = round(cam_data.dof.aperture_fstop, 2)
    return info


# ----------------------------------------------------------------------------------------
# motion for sequences (generate --sequence N)
# ----------------------------------------------------------------------------------------
CONTENT = []  # names of the content objects of the last build() (candidates to move)


def _linear_keys(ob):
    for fc in ob.animation_data.action.fcurves:
        fc.extrapolation = "LINEAR"  # frames 0 and N+1 move on: vectors on the end frames too
        for kp in fc.keyframe_points:
            kp.interpolation = "LINEAR"


def add_motion(family, seed, n_frames, frame, crop):
    """Animate the built scene over frames 1..n_frames (linear keys, linear extrapolation):
    the camera trucks sideways, dollies and pans, and the content object seen nearest the
    crop's centre slides over the ground and spins.  The middle of the sequence is the scene
    as built.  Image speeds are drawn in pixels per frame (at the frame's resolution) and
    capped so that the whole sequence moves the view by at most ~0.35 (camera) and ~0.5
    (object) of the crop.  Deterministic from (family, seed, n_frames, frame, crop); the scene's
    own random draws are untouched (a separate generator)."""
    from bpy_extras.object_utils import world_to_camera_view
    rng = random.Random(f"motion:{family}:{seed}")
    scene = bpy.context.scene
    cam = scene.camera
    fw, fh = frame
    x0, y0, cw, ch = crop
    f_px = cam.data.lens / cam.data.sensor_width * max(fw, fh)  # pixels per radian
    steps = max(n_frames - 1, 1)
    mid = (n_frames + 1) / 2.0
    bpy.context.view_layer.update()
    cm = cam.matrix_world.copy()
    right, up, back = (cm.to_3x3() @ Vector(v) for v in ((1, 0, 0), (0, 1, 0), (0, 0, 1)))
    cam_loc = cm.translation.copy()
    # the content object nearest the crop's centre (in view), else the nearest in view
    ccx, ccy = (x0 + cw / 2) / fw, 1.0 - (y0 + ch / 2) / fh
    best = None
    for name in CONTENT:
        ob = bpy.data.objects.get(name)
        if ob is None:
            continue
        v = world_to_camera_view(scene, cam, ob.matrix_world.translation)
        if v.z <= 0:
            continue
        d = math.hypot(v.x - ccx, (v.y - ccy) * fh / fw)
        if best is None or d < best[0]:
            best = (d, ob, v.z)
    depth = best[2] if best else 5.0
    # camera: truck + pan (image shift in px/frame) and a dolly (fraction of depth per frame)
    cam_px = min(rng.uniform(1.0, 3.0), 0.35 * cw / steps)
    split = rng.uniform(0.0, 1.0)  # truck vs pan share of the image shift
    sgn = rng.choice([-1, 1])
    truck = sgn * split * cam_px * depth / f_px  # world units per frame along camera right
    pan = sgn * (1.0 - split) * cam_px / f_px  # radians per frame about world Z
    pan *= 1.0 if rng.random() < 0.7 else -1.0  # sometimes against the truck (parallax)
    dolly = rng.uniform(-0.01, 0.015) * depth  # towards the view (+) or away (-) per frame
    rise = rng.gauss(0.0, 0.3) * cam_px * depth / f_px  # a little vertical drift
    fwd = -back
    rot0 = cam.rotation_euler.copy()
    for fr in (1, n_frames):
        t = fr - mid
        cam.location = cam_loc + right * (truck * t) + fwd * (dolly * t) + up * (rise * t)
        cam.rotation_euler = (rot0.x, rot0.y, rot0.z + pan * t)
        cam.keyframe_insert("location", frame=fr)
        cam.keyframe_insert("rotation_euler", frame=fr)
    _linear_keys(cam)
    cam.location, cam.rotation_euler = cam_loc, rot0
    info = {"frames": n_frames, "middle_frame": mid,
            "camera": {"truck_per_frame": round(truck, 5), "pan_deg_per_frame": round(math.degrees(pan), 4),
                       "dolly_per_frame": round(dolly, 5), "rise_per_frame": round(rise, 5),
                       "image_px_per_frame": round(cam_px, 3)}}
    if best is not None:
        ob = best[1]
        obj_px = min(rng.uniform(2.0, 5.0), 0.5 * cw / steps)
        # slide along the camera's horizontal axis on the ground, turned by up to 45 degrees
        h = Vector((right.x, right.y, 0.0))
        h = h.normalized() if h.length > 1e-6 else Vector((1, 0, 0))
        a = rng.uniform(-math.pi / 4, math.pi / 4) + (math.pi if rng.random() < 0.5 else 0.0)
        d = Vector((h.x * math.cos(a) - h.y * math.sin(a), h.x * math.sin(a) + h.y * math.cos(a), 0.0))
        speed = obj_px * best[2] / f_px
        spin = math.radians(rng.uniform(1.0, 4.0)) * rng.choice([-1, 1])
        loc0, r0 = ob.location.copy(), ob.rotation_euler.copy()
        for fr in (1, n_frames):
            t = fr - mid
            ob.location = loc0 + d * (speed * t)
            ob.rotation_euler = (r0.x, r0.y, r0.z + spin * t)
            ob.keyframe_insert("location", frame=fr)
            ob.keyframe_insert("rotation_euler", frame=fr)
        _linear_keys(ob)
        ob.location, ob.rotation_euler = loc0, r0
        info["object"] = {"name": ob.name, "direction": [round(v, 4) for v in d],
                          "speed_per_frame": round(speed, 5), "image_px_per_frame": round(obj_px, 3),
                          "spin_deg_per_frame": round(math.degrees(spin), 3)}
    scene.frame_start, scene.frame_end = 1, n_frames
    return info


# ----------------------------------------------------------------------------------------
# entry point
# ----------------------------------------------------------------------------------------
def build(family, seed):
    if family not in FAMILIES + EXTRA_FAMILIES:
        raise ValueError(f"unknown family {family}; known: {FAMILIES + EXTRA_FAMILIES}")
    CONTENT.clear()
    rng = random.Random(f"{family}:{seed}")
    if family == "caustics":
        return build_caustics(rng, seed)
    if family in EXTRA_FAMILIES:
        import scenes_more  # imports this module: only once it is loaded
        return scenes_more.build(family, rng, seed)
    clear_scene()
    stage_name = rng.choice(FAMILY_STAGES[family])
    st = STAGES[stage_name](rng, family)
    info = {"family": family, "seed": seed, "stage": st.info}
    n = rng.randint(4, 12) if family != "fine" else rng.randint(1, 5)
    arrangement, objs = place_content(rng, st, family, n)
    made, mats = build_objects(rng, objs, family)
    CONTENT.extend(ob.name for ob in made)
    info["arrangement"] = arrangement
    info["objects"] = [{"prim": o["prim"], "size": round(o["size"], 3),
                        "loc": [round(x, 3) for x in o["loc"]], "material": m}
                       for o, m in zip(objs, mats)]
    targets = [o["loc"] for o in objs]
    if family == "emissive":
        info["emitters"] = add_emitters(rng, st, rng.randint(2, 10))
        if rng.random() < 0.6:  # aim at an emitter: visible bright sources in the crop
            targets = [e["loc"] for e in info["emitters"]]
        # dim the main lights: emitters dominate and make heavy-tailed noise
        for ob in bpy.data.objects:
            if ob.type == "LIGHT":
                ob.data.energy *= rng.uniform(0.05, 0.4)
        if bpy.context.scene.world is not None and "Background" in bpy.context.scene.world.node_tree.nodes:
            bg = bpy.context.scene.world.node_tree.nodes["Background"]
            bg.inputs["Strength"].default_value *= 0.2
    elif rng.random() < 0.2:
        info["emitters"] = add_emitters(rng, st, rng.randint(1, 3))
    if family == "fine":
        (x0, y0), (x1, y1) = st.content_box
        c = (rng.uniform(x0, x1), rng.uniform(y0, y1))
        kinds = rng.sample(["grass", "wires", "fur"], rng.randint(1, 3))
        fine = {}
        if "grass" in kinds:
            fine["grass"] = add_grass(rng, st, c, st.scale * rng.uniform(2, 5), rng.randint(3000, 12000))
            targets.append((c[0], c[1], st.scale * 0.3))
        if "wires" in kinds:
            fine["wires"] = add_wires(rng, st, c)
            targets.append((c[0], c[1], st.scale))
        if "fur" in kinds and made:
            for ob in rng.sample(made, min(len(made), rng.randint(1, 3))):
                fine.setdefault("fur", []).append(add_fur(rng, ob, st))
        info["fine"] = fine
        bpy.context.scene.cycles_curves.shape = rng.choice(["RIBBONS", "THICK"])
    cam, cinfo = setup_camera(rng, st, targets, family)
    info["camera"] = cinfo
    return info
