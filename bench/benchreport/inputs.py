"""Which renders the report runs on: scene directories in the layout of ../shared/data.

Two layouts are read, the ones every tool of the project reads:
  box layout   <stem>_NNNNspp.exr with _var, _A, _B beside it and <stem>_ref.exr
               (Blender Cycles: shared/data/box, the generated crops, tests/data/box16)
  tungsten     a directory of color.pfm, colorA.pfm, ... and ref.pfm (shared/data/tungsten/*);
               16 spp
"""
import os
import re
from dataclasses import dataclass, field

SPP_FILE = re.compile(r"^(?P<stem>.+)_(?P<spp>\d{4})spp\.exr$")


@dataclass
class Render:
    """One noisy render with its reference: what one row of runs starts from."""
    group: str       # "shared", "generated", "caustics", "scaling", "custom": how the report
                     # aggregates it
    scene: str       # levels of one scene share it (error vs spp)
    spp: int
    preset: str      # mcdntool --aov:preset
    inputs: list     # [(path, kind)] with kind mean | variance | halfA | halfB
    reference: str
    width: int = 0
    height: int = 0
    notes: dict = field(default_factory=dict)

    @property
    def key(self):
        return f"{self.scene}_{self.spp:04d}spp"

    @property
    def pixels(self):
        return self.width * self.height

    def color_channels(self):
        return (["ViewLayer.Combined.R", "ViewLayer.Combined.G", "ViewLayer.Combined.B"]
                if self.preset == "cycles" else ["R", "G", "B"])


def box_layout_renders(directory, group, scene=None):
    """Every spp level of a box-layout directory that has all four files and a reference."""
    renders = []
    for name in sorted(os.listdir(directory)):
        match = SPP_FILE.match(name)
        if not match:
            continue
        stem = os.path.join(directory, match["stem"])
        level = f"{stem}_{match['spp']}spp"
        files = [(level + ".exr", "mean"), (level + "_var.exr", "variance"),
                 (level + "_A.exr", "halfA"), (level + "_B.exr", "halfB")]
        reference = stem + "_ref.exr"
        if all(os.path.exists(f) for f, _ in files) and os.path.exists(reference):
            renders.append(Render(group, scene or match["stem"], int(match["spp"]), "cycles",
                                  files, reference))
    return renders


def tungsten_renders(directory, group, scene=None):
    """A Tungsten buffer directory (16 spp in shared/data) as one render."""
    if not (os.path.exists(os.path.join(directory, "color.pfm"))
            and os.path.exists(os.path.join(directory, "ref.pfm"))):
        return []
    return [Render(group, scene or os.path.basename(os.path.normpath(directory)), 16, "tungsten",
                   [(directory, "mean")], os.path.join(directory, "ref.pfm"))]


def renders_in(directory, group, scene=None):
    """Whatever layout `directory` has (box or tungsten); [] if neither."""
    return box_layout_renders(directory, group, scene) or tungsten_renders(directory, group, scene)


def shared_renders(shared_data):
    """box 16/64/256 spp, tungsten cornell20 and materialtest; [] when ../shared is absent."""
    renders = []
    if os.path.isdir(os.path.join(shared_data, "box")):
        renders += box_layout_renders(os.path.join(shared_data, "box"), "shared")
    for scene in ("cornell20", "materialtest"):
        directory = os.path.join(shared_data, "tungsten", scene)
        if os.path.isdir(directory):
            renders += tungsten_renders(directory, "shared")
    return renders


def cached_dataset(*names):
    """The first of $MCDN_CACHE (~/.cache/mcdenoise)/datasets/NAME that exists, else None.
    (bench/bench_data.h finds the same cache for the C++ benchmarks.)"""
    cache = os.environ.get("MCDN_CACHE") or os.path.join(os.path.expanduser("~"), ".cache/mcdenoise")
    for name in names:
        root = os.path.join(cache, "datasets", name)
        if os.path.isdir(root):
            return root
    return None


def generated_dataset():
    """The generator's held-out crops: datasets/eval, else the --small set (its seeds never
    overlap training's); None when neither was rendered."""
    return cached_dataset("eval", "small")


def caustics_dataset():
    """The caustics crops (training/datagen --families caustics, issue 22's heavy tails);
    None when they were not rendered."""
    return cached_dataset("caustics")


def crop_renders(root, group):
    """Every level of every crop directory under a dataset root (generated, caustics)."""
    renders = []
    for crop in sorted(os.listdir(root)):
        directory = os.path.join(root, crop)
        if os.path.isdir(directory) and not crop.startswith("."):
            renders += box_layout_renders(directory, group, crop)
    return renders


def scaling_renders(source, sizes, workdir):
    """`source` cut (sizes below its own) or tiled (above) to square sizes, reference too, so
    time against pixel count spans more than the scenes' own sizes. Box layout only."""
    import OpenImageIO as oiio
    renders = []
    for size in sizes:
        directory = os.path.join(workdir, f"scaling_{size}")
        os.makedirs(directory, exist_ok=True)
        stem = os.path.join(directory, f"{source.scene}{size}")
        files = [(f"{stem}_{source.spp:04d}spp{suffix}.exr", kind)
                 for suffix, kind in (("", "mean"), ("_var", "variance"), ("_A", "halfA"), ("_B", "halfB"))]
        for (src_path, _), (dst_path, _) in zip(source.inputs + [(source.reference, "")],
                                                files + [(stem + "_ref.exr", "")]):
            if not os.path.exists(dst_path):
                write_square(oiio.ImageBuf(src_path), size, dst_path)
        renders.append(Render("scaling", f"{source.scene}{size}", source.spp, source.preset, files,
                              stem + "_ref.exr", notes={"made_from": source.key}))
    return renders


def write_square(image, size, path):
    """size x size: the top-left cut of `image`, or `image` repeated (seams and all)."""
    import OpenImageIO as oiio
    spec = image.spec()
    if size <= spec.width and size <= spec.height:
        square = oiio.ImageBufAlgo.cut(image, oiio.ROI(0, size, 0, size, 0, 1, 0, spec.nchannels))
    else:
        out_spec = oiio.ImageSpec(size, size, spec.nchannels, "float")
        out_spec.channelnames = spec.channelnames
        square = oiio.ImageBuf(out_spec)
        for y in range(0, size, spec.height):
            for x in range(0, size, spec.width):
                oiio.ImageBufAlgo.paste(square, x, y, 0, 0, image)
        square = oiio.ImageBufAlgo.cut(square, oiio.ROI(0, size, 0, size, 0, 1, 0, spec.nchannels))
    square.specmod().attribute("compression", "zip")
    if not square.write(path, "float"):
        raise RuntimeError(f"{path}: {square.geterror()}")
