"""No lower layer of the library includes a higher one.

    check_layers.py [ROOT]     exits 1 and names each offending include

Layers, lowest first (a file may include its own layer and those below it):
  0 foundation  lib/src/{core,aov,io,color,metrics,skip}/, mcdn/{aov,io,color,metrics,skip,
                progress,
                threads,version}.h: what every op stands on
  1 engines     lib/src/{nl_means,nn,outliers}/: the NL-means filter, the network engine and
                the heavy-tailed samples' detection
  2 stages      lib/src/{prefilter,nfor,cnn,sure,mix,frames}/ and their public headers
  3 chains      lib/src/chain/, mcdn/{chain,settings,denoise}.h: the only code that knows
                every stage
Public headers follow the same rule by the layer of the header itself.
"""
import os
import re
import sys

FOLDERS = {
    "core": 0, "aov": 0, "io": 0, "color": 0, "metrics": 0, "skip": 0,
    "nl_means": 1, "nn": 1, "outliers": 1,
    "prefilter": 2, "nfor": 2, "cnn": 2, "sure": 2, "mix": 2, "frames": 2,
    "chain": 3,
}
HEADERS = {
    "aov": 0, "io": 0, "color": 0, "metrics": 0, "skip": 0, "threads": 0, "version": 0,
    "progress": 0,
    "prefilter": 2, "nfor": 2, "cnn": 2, "sure": 2, "mix": 2, "frames": 2,
    "chain": 3, "settings": 3, "denoise": 3,
}
INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"', re.M)


def layer_of_include(path):
    """The layer an included "folder/file.h" or "mcdn/name.h" belongs to (None: not ours)."""
    head, _, name = path.partition("/")
    if head == "mcdn":
        return HEADERS.get(os.path.splitext(name)[0])
    return FOLDERS.get(head)


def main():
    root = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "..", "..")
    lib = os.path.join(root, "lib")
    problems, unknown = [], []
    for base, dirs, files in os.walk(lib):
        for f in sorted(files):
            if not f.endswith((".h", ".cpp")):
                continue
            path = os.path.join(base, f)
            rel = os.path.relpath(path, lib)
            parts = rel.split(os.sep)
            if parts[0] == "include":
                layer = HEADERS.get(os.path.splitext(f)[0])
            else:
                layer = FOLDERS.get(parts[1])
            if layer is None:
                unknown.append(rel)
                continue
            text = open(path, encoding="utf-8").read()
            for included in INCLUDE.findall(text):
                target = layer_of_include(included)
                if target is not None and target > layer:
                    problems.append("%s (layer %d) includes %s (layer %d)" %
                                    (rel, layer, included, target))
    for rel in unknown:
        problems.append("%s: in no layer (add its folder to tests/layers/check_layers.py)" % rel)
    for p in problems:
        print("layers: " + p)
    print("layers: %d problem(s)" % len(problems))
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
