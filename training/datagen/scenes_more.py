"""The fourteen scene families beyond scenes.py's ten (issue 47): what production frames have
that the first families lack. Each family is a stage of scenes.py (or one of its own), a
material mix and a finishing step that adds the family's subject; ``build(family, rng)``
returns the drawn parameters like scenes.build. Runs inside Blender 3.4.

| family | subject |
|---|---|
| window | rooms lit through a window by sun and sky alone (no lamp inside) |
| many_lights | 10-40 small coloured point and spot lights, the stage's own lights dimmed |
| screens | emissive screens showing procedural images in dim rooms |
| volume | fog: a homogeneous scattering volume round the content, light shafts |
| subsurface | skin, wax, marble, jade: random-walk subsurface scattering |
| foliage | plants: stems and thousands of thin translucent leaves |
| motion_blur | moving and spinning objects under a shutter of 0.3-1 frame |
| water | a rippled water surface over a tiled floor: refraction and caustics from the sun |
| glossy | near-mirror plastics and metals before a polished floor: glossy inter-reflection |
| carpaint | metallic base under a clear coat, with flakes |
| anisotropic | brushed and anisotropic metals |
| text | lettering at many sizes and fine high-frequency textures |
| hdri | product shots lit by a procedural environment with bright softbox spots |
| night | exteriors at night: dim moon and sky, a few warm street lamps |
"""
import math

import bpy
from mathutils import Vector

import scenes as S

FAMILIES = ["window", "many_lights", "screens", "volume", "subsurface", "foliage", "motion_blur",
            "water", "glossy", "carpaint", "anisotropic", "text", "hdri", "night"]

STAGES = {
    "window": ["window_room"],
    "many_lights": ["room", "corridor", "studio", "indirect_room"],
    "screens": ["room", "corridor", "indirect_room"],
    "volume": ["ground", "room", "window_room", "corridor", "colonnade"],
    "subsurface": ["studio", "room", "window_room", "ground"],
    "foliage": ["ground", "terrain", "studio", "window_room"],
    "motion_blur": ["room", "ground", "studio", "corridor", "city"],
    "water": ["ground", "studio"],
    "glossy": ["room", "studio", "corridor", "indirect_room"],
    "carpaint": ["studio", "ground", "city"],
    "anisotropic": ["studio", "room", "window_room"],
    "text": ["room", "studio", "corridor", "ground"],
    "hdri": ["hdri"],
    "night": ["ground", "city", "colonnade", "terrain"],
}

MATERIALS = {
    "window": {"diffuse": 3, "textured": 2, "plastic": 1, "metal": 1, "glass": 0.5},
    "many_lights": {"diffuse": 2, "plastic": 2, "metal": 2, "textured": 1, "glass": 1},
    "screens": {"diffuse": 2, "plastic": 2, "metal": 1, "textured": 1},
    "volume": {"diffuse": 3, "textured": 1, "metal": 1, "plastic": 1},
    "subsurface": {"subsurface": 8, "diffuse": 1, "plastic": 1},
    "foliage": {"diffuse": 2, "textured": 2, "plastic": 1},
    "motion_blur": {"textured": 3, "diffuse": 2, "plastic": 2, "metal": 1},
    "water": {"diffuse": 2, "textured": 2, "plastic": 1, "metal": 1},
    "glossy": {"mirror_plastic": 4, "metal": 3, "coated": 2},
    "carpaint": {"carpaint": 8, "metal": 1, "glass": 0.5},
    "anisotropic": {"anisotropic": 8, "plastic": 1},
    "text": {"textured": 3, "diffuse": 2, "plastic": 1},
    "hdri": {"metal": 3, "mirror_plastic": 2, "glass": 2, "carpaint": 1, "subsurface": 1},
    "night": {"diffuse": 3, "textured": 2, "metal": 1, "coated": 1, "glass": 0.5},
}

SMOOTH_PRIMS = ["sphere", "torus", "monkey", "cylinder", "cone"]


def _rnd(v, n=3):
    return [round(x, n) for x in v] if isinstance(v, (tuple, list, Vector)) else round(v, n)


# ----------------------------------------------------------------------------------------
# materials these families add to scenes.make_material's
# ----------------------------------------------------------------------------------------
SSS_LOOKS = {  # base colour, radius (m, per RGB) of skin, wax, marble, jade, milk
    "skin": ((0.8, 0.5, 0.4), (0.010, 0.004, 0.002)),
    "wax": ((0.9, 0.8, 0.55), (0.02, 0.015, 0.008)),
    "marble": ((0.85, 0.85, 0.8), (0.008, 0.008, 0.008)),
    "jade": ((0.3, 0.7, 0.4), (0.01, 0.03, 0.012)),
    "milk": ((0.95, 0.93, 0.88), (0.03, 0.03, 0.025)),
}


def make_material(rng, kind, name="mat"):
    if kind not in ("subsurface", "mirror_plastic", "carpaint", "anisotropic"):
        return S.make_material(rng, kind, name)
    m, nt, p = S.new_material(name)
    info = {"kind": kind}
    if kind == "subsurface":
        look = rng.choice(list(SSS_LOOKS))
        base, radius = SSS_LOOKS[look]
        base = tuple(min(1.0, c * rng.uniform(0.8, 1.1)) for c in base)
        scale = math.exp(rng.uniform(math.log(0.5), math.log(8)))
        p.subsurface_method = "RANDOM_WALK"
        S.set_p(p, base=base, rough=rng.uniform(0.2, 0.6), spec=0.5)
        p.inputs["Subsurface"].default_value = 1.0
        p.inputs["Subsurface Radius"].default_value = tuple(r * scale for r in radius)
        p.inputs["Subsurface Color"].default_value = (*base, 1)
        info.update({"look": look, "radius_scale": round(scale, 3)})
    elif kind == "mirror_plastic":
        S.set_p(p, base=S.rand_color(rng), rough=rng.uniform(0.0, 0.12), spec=rng.uniform(0.5, 1.0))
    elif kind == "carpaint":
        base = S.rand_color(rng, sat=(0.5, 1.0), val=(0.3, 0.9))
        S.set_p(p, base=base, metallic=rng.uniform(0.3, 1.0), rough=rng.uniform(0.2, 0.5),
                coat=1.0, coat_rough=rng.uniform(0.0, 0.06))
        # flakes: a fine voronoi bump on the base layer only (the coat keeps its own normal)
        info["flakes"] = S.add_bump(nt, p, rng, scale=math.exp(rng.uniform(math.log(200), math.log(800))),
                                    kind="voronoi")
    else:  # anisotropic
        cname = rng.choice(list(S.METAL_COLORS))
        S.set_p(p, base=S.METAL_COLORS[cname], metallic=1.0, rough=rng.uniform(0.1, 0.5),
                aniso=rng.uniform(0.5, 1.0), aniso_rot=rng.random())
        if rng.random() < 0.6:  # brushed: fine bands along one axis
            info["brushed"] = S.add_bump(nt, p, rng, scale=math.exp(rng.uniform(math.log(50), math.log(300))),
                                         kind="wave")
        info["metal"] = cname
    return m, info


def build_objects(rng, family, objs, prims=None):
    made, infos = [], []
    for o in objs:
        mat, minfo = make_material(rng, S.weighted(rng, MATERIALS[family]), "obj")
        kind = rng.choice(prims) if prims else o["prim"]
        o["prim"] = kind
        s = o["size"]
        scale = (s, s, s * 1.0) if kind != "cylinder" else (s * 0.6, s * 0.6, s)
        rot = (rng.uniform(0, 1.6) if kind == "torus" else 0, 0, rng.uniform(0, 6.3))
        made.append(S.add_prim(kind, tuple(o["loc"]), scale, rot, mat))
        infos.append(minfo)
    return made, infos


# ----------------------------------------------------------------------------------------
# lights and props
# ----------------------------------------------------------------------------------------
def point_light(loc, energy, color, radius, kind="POINT", target=None, spot_deg=45):
    ld = bpy.data.lights.new("pt", kind)
    ld.energy = energy
    ld.color = color
    ld.shadow_soft_size = radius
    if kind == "SPOT":
        ld.spot_size = math.radians(spot_deg)
        ld.spot_blend = 0.3
    ob = bpy.data.objects.new("pt", ld)
    bpy.context.scene.collection.objects.link(ob)
    ob.location = loc
    if target is not None:
        S.look_at(ob, target)
    return ob


def dim_lights(rng, lo, hi, world_lo=None, world_hi=None):
    f = rng.uniform(lo, hi)
    for ob in bpy.data.objects:
        if ob.type == "LIGHT":
            ob.data.energy *= f
    world = bpy.context.scene.world
    if world is not None and world.use_nodes and "Background" in world.node_tree.nodes:
        bg = world.node_tree.nodes["Background"]
        bg.inputs["Strength"].default_value *= rng.uniform(world_lo if world_lo is not None else lo,
                                                            world_hi if world_hi is not None else hi)
    return round(f, 4)


def content_point(rng, st, z_lo, z_hi):
    (x0, y0), (x1, y1) = st.content_box
    return (rng.uniform(x0, x1), rng.uniform(y0, y1), rng.uniform(z_lo, z_hi))


# ----------------------------------------------------------------------------------------
# the families' finishing steps: (rng, stage, made objects, info, targets) -> targets
# ----------------------------------------------------------------------------------------
def finish_window(rng, st, made, info, targets):
    for ob in list(bpy.data.objects):
        if ob.type == "LIGHT" and ob.data.type == "AREA":
            bpy.data.objects.remove(ob, do_unlink=True)
    sun = bpy.data.objects["sun"]
    sun.data.energy *= rng.uniform(1.0, 2.5)
    info["sun_energy"] = _rnd(sun.data.energy)
    return targets


def finish_many_lights(rng, st, made, info, targets):
    info["dimmed"] = dim_lights(rng, 0.0, 0.08)
    n = rng.randint(10, 40)
    lights = []
    for _ in range(n):
        loc = content_point(rng, st, 0.1 * st.scale, 8 * st.scale)
        col = S.rand_color(rng, sat=(0.0, 1.0), val=(0.9, 1.0))
        e = math.exp(rng.uniform(math.log(0.5), math.log(60))) * st.scale
        spot = rng.random() < 0.3
        point_light(loc, e, col, rng.uniform(0.0, 0.08) * st.scale, "SPOT" if spot else "POINT",
                    target=(loc[0], loc[1], 0) if spot else None, spot_deg=rng.uniform(20, 80))
        lights.append({"loc": _rnd(loc), "energy": _rnd(e), "spot": spot})
    info["lights"] = lights
    return targets


def finish_screens(rng, st, made, info, targets):
    info["dimmed"] = dim_lights(rng, 0.03, 0.3)
    screens = []
    for i in range(rng.randint(1, 4)):
        m, nt, p = S.new_material("screen")
        col, _, tinfo = S.texture_node(nt, rng, rng.choice(S.TEXTURES),
                                       math.exp(rng.uniform(math.log(2), math.log(40))))
        S.set_p(p, base=(0.02, 0.02, 0.02), rough=rng.uniform(0.05, 0.3))
        nt.links.new(col, p.inputs["Emission"])
        strength = math.exp(rng.uniform(math.log(2), math.log(40)))
        p.inputs["Emission Strength"].default_value = strength
        c = content_point(rng, st, 0.5 * st.scale, 5 * st.scale)
        w = st.scale * rng.uniform(1.5, 5)
        S.quad("screen", c, (w, w * rng.choice([0.5625, 0.75, 0.42])),
                    (math.pi / 2, 0, rng.uniform(0, 6.3)), m)
        targets.append(tuple(c))
        screens.append({"center": _rnd(c), "width": _rnd(w), "strength": _rnd(strength), **tinfo})
    info["screens"] = screens
    return targets


def finish_volume(rng, st, made, info, targets):
    (x0, y0), (x1, y1) = st.content_box
    m = bpy.data.materials.new("fog")
    m.use_nodes = True
    nt = m.node_tree
    nt.nodes.remove(nt.nodes["Principled BSDF"])
    vol = nt.nodes.new("ShaderNodeVolumePrincipled")
    density = math.exp(rng.uniform(math.log(0.03), math.log(0.5)))  # per metre
    vol.inputs["Density"].default_value = density
    vol.inputs["Anisotropy"].default_value = rng.uniform(0.0, 0.8)
    vol.inputs["Color"].default_value = (*S.rand_color(rng, sat=(0.0, 0.3), val=(0.7, 1.0)), 1)
    nt.links.new(vol.outputs["Volume"], nt.nodes["Material Output"].inputs["Volume"])
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    half = max(x1 - x0, y1 - y0) * 2 + 20 * st.scale
    S.add_prim("cube", (cx, cy, half / 2), (half, half, half / 2), mat=m).modifiers.clear()
    bpy.context.scene.cycles.volume_bounces = rng.choice([0, 1, 2])
    if rng.random() < 0.6:  # a spot through the fog: a visible shaft
        loc = content_point(rng, st, 6 * st.scale, 12 * st.scale)
        point_light(loc, rng.uniform(200, 2000) * st.scale ** 2, (1, rng.uniform(0.8, 1), rng.uniform(0.6, 1)),
                    0.02, "SPOT", target=targets[0] if targets else (cx, cy, 0), spot_deg=rng.uniform(15, 50))
    info["fog"] = {"density": _rnd(density, 4), "anisotropy": _rnd(vol.inputs["Anisotropy"].default_value)}
    return targets


def finish_foliage(rng, st, made, info, targets):
    m, nt, p = S.new_material("leaf")
    if rng.random() < 0.6:
        col, _, _ = S.texture_node(nt, rng, "noise", rng.uniform(5, 40))
        nt.links.new(col, p.inputs["Base Color"])
    else:
        S.set_p(p, base=S.rand_color(rng, sat=(0.4, 0.9), val=(0.15, 0.6)))
    S.set_p(p, rough=rng.uniform(0.3, 0.7), spec=0.4)
    mix = nt.nodes.new("ShaderNodeMixShader")
    tr = nt.nodes.new("ShaderNodeBsdfTranslucent")
    tr.inputs["Color"].default_value = (0.3, 0.6, 0.1, 1)
    mix.inputs["Fac"].default_value = rng.uniform(0.1, 0.4)
    out = nt.nodes["Material Output"]
    nt.links.new(p.outputs["BSDF"], mix.inputs[1])
    nt.links.new(tr.outputs["BSDF"], mix.inputs[2])
    nt.links.new(mix.outputs["Shader"], out.inputs["Surface"])
    stem_mat, _ = S.make_material(rng, "diffuse", "stem")
    plants = []
    for _ in range(rng.randint(1, 3)):
        base = content_point(rng, st, 0, 0)
        height = st.scale * rng.uniform(2, 6)
        S.add_prim("cylinder", (base[0], base[1], height / 2), (0.02 * st.scale, 0.02 * st.scale, height / 2),
                   mat=stem_mat)
        crown = Vector((base[0], base[1], height * rng.uniform(0.6, 1.0)))
        radius = st.scale * rng.uniform(0.8, 2.5)
        leaf = st.scale * rng.uniform(0.05, 0.25)
        n = rng.randint(1500, 6000)
        verts, faces = [], []
        for i in range(n):
            d = Vector((rng.gauss(0, 1), rng.gauss(0, 1), rng.gauss(0, 0.7))).normalized()
            c = crown + d * radius * rng.random() ** 0.5
            a = Vector((rng.gauss(0, 1), rng.gauss(0, 1), rng.gauss(0, 1))).normalized()
            b = a.cross(d).normalized() if a.cross(d).length > 1e-3 else Vector((1, 0, 0))
            w = leaf * rng.uniform(0.2, 0.45)
            k = len(verts)
            verts += [c - a * leaf * 0.5, c + b * w, c + a * leaf * 0.5, c - b * w]
            faces.append((k, k + 1, k + 2, k + 3))
        S.mesh_object("leaves", [tuple(v) for v in verts], faces, m)
        targets.append(tuple(crown))
        plants.append({"base": _rnd(base), "height": _rnd(height), "leaves": n, "leaf": _rnd(leaf)})
    info["plants"] = plants
    return targets


def finish_motion_blur(rng, st, made, info, targets):
    scene = bpy.context.scene
    scene.render.use_motion_blur = True
    scene.render.motion_blur_shutter = rng.uniform(0.3, 1.0)
    moved = []
    for ob in rng.sample(made, min(len(made), rng.randint(1, 4))):
        v = Vector((rng.gauss(0, 1), rng.gauss(0, 1), rng.gauss(0, 0.3))) * st.scale * rng.uniform(0.2, 2.0)
        spin = math.radians(rng.uniform(-60, 60))
        p0, r0 = Vector(ob.location), ob.rotation_euler.copy()
        for frame, t in ((0, -1), (2, 1)):
            ob.location = p0 + v * t
            ob.rotation_euler = (r0.x, r0.y, r0.z + spin * t)
            ob.keyframe_insert("location", frame=frame)
            ob.keyframe_insert("rotation_euler", frame=frame)
        S._linear_keys(ob)
        moved.append({"velocity": _rnd(v), "spin_deg": _rnd(math.degrees(spin), 1)})
    scene.frame_set(1)
    info["motion_blur"] = {"shutter": _rnd(scene.render.motion_blur_shutter), "moved": moved}
    return targets


def finish_water(rng, st, made, info, targets):
    (x0, y0), (x1, y1) = st.content_box
    tiles, tinfo = S.make_material(rng, "textured", "pool")
    span = max(x1 - x0, y1 - y0) * 1.6 + 4 * st.scale
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    S.quad("pool_floor", (cx, cy, 0.002), (span, span), (0, 0, 0), tiles)
    depth = st.scale * rng.uniform(0.3, 1.5)
    m, nt, p = S.new_material("water")
    S.set_p(p, base=(1, 1, 1), transmission=1.0, rough=rng.choice([0.0, 0.0, rng.uniform(0.01, 0.08)]),
            ior=1.33, spec=0.5)
    info["waves"] = S.add_bump(nt, p, rng, scale=rng.uniform(0.5, 6) / st.scale,
                               kind=rng.choice(["noise", "wave", "voronoi"]))
    water = S.add_prim("cube", (cx, cy, depth / 2), (span / 2, span / 2, depth / 2), mat=m)
    water.modifiers.clear()
    bpy.context.scene.cycles.caustics_refractive = True
    info["water"] = {"depth": _rnd(depth), "span": _rnd(span), "floor": tinfo}
    return targets


def finish_glossy(rng, st, made, info, targets):
    floor = bpy.data.objects.get("floor") or bpy.data.objects.get("cyc")
    if floor is not None:
        m, minfo = make_material(rng, rng.choice(["mirror_plastic", "metal", "coated"]), "polished")
        floor.data.materials.clear()
        floor.data.materials.append(m)
        info["floor"] = minfo
    return targets


def finish_text(rng, st, made, info, targets):
    words = ["MCDENOISE", "Exit", "42", "Open 24h", "CAFE", "Lorem ipsum dolor", "ABCDEFG",
             "0123456789", "Nord", "HOTEL", "sale -50%", "No parking", "a quick brown fox"]
    texts = []
    for _ in range(rng.randint(3, 12)):
        cu = bpy.data.curves.new("txt", "FONT")
        cu.body = rng.choice(words)
        cu.size = st.scale * math.exp(rng.uniform(math.log(0.3), math.log(3.0)))
        cu.extrude = cu.size * rng.choice([0.0, 0.02, 0.1])
        cu.align_x = "CENTER"
        ob = bpy.data.objects.new("txt", cu)
        bpy.context.scene.collection.objects.link(ob)
        loc = content_point(rng, st, 0.01, 4 * st.scale)
        ob.location = loc
        ob.rotation_euler = (rng.choice([0.0, math.pi / 2]), 0, rng.uniform(0, 6.3))
        m, _ = S.make_material(rng, rng.choice(["diffuse", "plastic", "metal", "emissive"]), "ink")
        cu.materials.append(m)
        targets.append(tuple(loc))
        texts.append({"body": cu.body, "size": _rnd(cu.size), "loc": _rnd(loc)})
    info["texts"] = texts
    return targets


def stage_hdri(rng, family):
    """A product stage lit only by a procedural environment: broad colour variation plus a
    few bright, sharp 'softbox' spots (what an HDRI of a studio or a sky gives)."""
    st = S.Stage("hdri")
    w = bpy.data.worlds.new("env")
    w.use_nodes = True
    nt = w.node_tree
    bg = nt.nodes["Background"]
    col, _, tinfo = S.texture_node(nt, rng, "noise", rng.uniform(0.5, 3))
    # a world has no object: the texture varies with the direction (Generated)
    coord = next(n for n in nt.nodes if n.type == "TEX_COORD")
    mapping = next(n for n in nt.nodes if n.type == "MAPPING")
    nt.links.new(coord.outputs["Generated"], mapping.inputs["Vector"])
    nt.links.new(col, bg.inputs["Color"])
    bg.inputs["Strength"].default_value = rng.uniform(0.2, 1.0)
    spots = nt.nodes.new("ShaderNodeTexVoronoi")
    spots.inputs["Scale"].default_value = rng.uniform(1.5, 6)
    less = nt.nodes.new("ShaderNodeMath")
    less.operation = "LESS_THAN"
    less.inputs[1].default_value = rng.uniform(0.04, 0.2)
    gain = nt.nodes.new("ShaderNodeMath")
    gain.operation = "MULTIPLY"
    gain.inputs[1].default_value = math.exp(rng.uniform(math.log(10), math.log(200)))
    bright = nt.nodes.new("ShaderNodeBackground")
    bright.inputs["Color"].default_value = (1, rng.uniform(0.85, 1), rng.uniform(0.7, 1), 1)
    add = nt.nodes.new("ShaderNodeAddShader")
    nt.links.new(spots.outputs["Distance"], less.inputs[0])
    nt.links.new(less.outputs["Value"], gain.inputs[0])
    nt.links.new(gain.outputs["Value"], bright.inputs["Strength"])
    nt.links.new(bg.outputs["Background"], add.inputs[0])
    nt.links.new(bright.outputs["Background"], add.inputs[1])
    nt.links.new(add.outputs["Shader"], nt.nodes["World Output"].inputs["Surface"])
    bpy.context.scene.world = w
    fm, finfo = S.floor_material(rng, family)
    S.add_prim("cylinder", (0, 0, -0.05), (3, 3, 0.05), mat=fm)
    st.info.update({"env": tinfo, "spot_gain": _rnd(gain.inputs[1].default_value), "floor": finfo})
    st.content_box = ((-1.2, -1.2), (1.2, 1.2))
    st.cam_box = ((-4, -4, 0.3), (4, 4, 3))
    st.scale = 0.35
    return st


def finish_night(rng, st, made, info, targets):
    info["dimmed"] = dim_lights(rng, 0.005, 0.04, 0.002, 0.02)
    sun = bpy.data.objects.get("sun")
    if sun is not None:
        sun.data.color = (0.6, 0.7, 1.0)
    lamps = []
    lamp_mat, _ = S.make_material(rng, "emissive", "bulb")
    for _ in range(rng.randint(2, 8)):
        x, y, _z = content_point(rng, st, 0, 0)
        h = st.scale * rng.uniform(3, 9)
        e = rng.uniform(20, 400) * st.scale ** 2
        point_light((x, y, h), e, (1, rng.uniform(0.6, 0.85), rng.uniform(0.3, 0.6)),
                    rng.uniform(0.02, 0.1) * st.scale)
        S.add_prim("sphere", (x, y, h + 0.12 * st.scale), (0.08 * st.scale,) * 3, mat=lamp_mat)
        lamps.append({"loc": _rnd((x, y, h)), "energy": _rnd(e)})
    info["lamps"] = lamps
    return targets


FINISH = {
    "window": finish_window, "many_lights": finish_many_lights, "screens": finish_screens,
    "volume": finish_volume, "foliage": finish_foliage, "motion_blur": finish_motion_blur,
    "water": finish_water, "glossy": finish_glossy, "text": finish_text, "night": finish_night,
}
PRIMS = {"carpaint": SMOOTH_PRIMS, "anisotropic": ["cylinder", "torus", "sphere", "cone"],
         "subsurface": ["sphere", "monkey", "torus", "cube", "cylinder"]}
COUNT = {"foliage": (1, 4), "hdri": (1, 5), "water": (3, 8), "text": (1, 5)}


def build(family, rng, seed):
    S.clear_scene()
    stage_name = rng.choice(STAGES[family])
    st = stage_hdri(rng, family) if stage_name == "hdri" else S.STAGES[stage_name](rng, family)
    info = {"family": family, "seed": seed, "stage": st.info}
    arrangement, objs = S.place_content(rng, st, family, rng.randint(*COUNT.get(family, (4, 12))))
    made, mats = build_objects(rng, family, objs, PRIMS.get(family))
    S.CONTENT.extend(ob.name for ob in made)
    info["arrangement"] = arrangement
    info["objects"] = [{"prim": o["prim"], "size": _rnd(o["size"]), "loc": _rnd(o["loc"]), "material": m}
                       for o, m in zip(objs, mats)]
    targets = [o["loc"] for o in objs]
    if family in FINISH:
        targets = FINISH[family](rng, st, made, info, targets)
    _, info["camera"] = S.setup_camera(rng, st, targets, family)
    return info
