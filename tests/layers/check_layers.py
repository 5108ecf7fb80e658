"""No lower layer of the library includes a higher one, and no two folders include each other.

    check_layers.py [ROOT]     exits 1 and names each offending include or cycle

Layers, lowest first (a file may include its own layer and those below it):
  0 foundation  lib/src/{core,aov,io,color,metrics,skip}/, mcdn/{aov,io,color,metrics,skip,
                progress,threads,version}.h: what every op stands on
  1 engines     lib/src/{nl_means,nn,outliers,ops}/: the NL-means filter, the network engine,
                the heavy-tailed samples' detection, and what the ops share above the
                foundation (frames in bands and in the working space, neighbouring frames
                aligned by their motion, the colour role read as planes)
  2 stages      every other folder of lib/src/ (prefilter, nfor, cnn, oidn, sure, choose, mix,
                frames, ...) and its public header mcdn/<folder>.h: a new stage's folder
                needs no line here
  3 chains      lib/src/chain/, mcdn/{chain,settings,stages,denoise}.h: the only code that
                knows every stage (the stage table, mcdn/stages.h)
Public headers follow the same rule by the layer of the header itself.

Within a layer, folders include each other one way only: a public header counts as its
folder's (mcdn/color.h is color/'s; mcdn/threads.h, version.h and progress.h are core/'s),
and any cycle of folders (core -> color -> core) is named with a file on each step.
"""
import os
import re
import sys

FOLDERS = {
    "core": 0, "aov": 0, "io": 0, "color": 0, "metrics": 0, "skip": 0,
    "nl_means": 1, "nn": 1, "outliers": 1, "ops": 1,
    "chain": 3,
}
STAGE_LAYER = 2  # every folder of lib/src/ not in FOLDERS (add_stage_folders)
HEADERS = {
    "aov": 0, "io": 0, "color": 0, "metrics": 0, "skip": 0, "threads": 0, "version": 0,
    "progress": 0,
    "chain": 3, "settings": 3, "stages": 3, "denoise": 3,
}
# The folder whose code a public header declares.
HEADER_FOLDER = {
    "aov": "aov", "io": "io", "color": "color", "metrics": "metrics", "skip": "skip",
    "threads": "core", "version": "core", "progress": "core",
    "chain": "chain", "settings": "chain", "stages": "chain", "denoise": "chain",
}


def add_stage_folders(lib):
    """Every folder of lib/src/ that FOLDERS does not place is a stage's, its public header
    mcdn/<folder>.h with it."""
    src = os.path.join(lib, "src")
    for name in sorted(os.listdir(src)) if os.path.isdir(src) else []:
        if os.path.isdir(os.path.join(src, name)) and name not in FOLDERS:
            FOLDERS[name] = STAGE_LAYER
            HEADERS.setdefault(name, STAGE_LAYER)
            HEADER_FOLDER.setdefault(name, name)


INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"', re.M)


def layer_of_include(path):
    """The layer an included "folder/file.h" or "mcdn/name.h" belongs to (None: not ours)."""
    head, _, name = path.partition("/")
    if head == "mcdn":
        return HEADERS.get(os.path.splitext(name)[0])
    return FOLDERS.get(head)


def folder_of_include(path):
    """The folder an included "folder/file.h" or "mcdn/name.h" belongs to (None: not ours)."""
    head, _, name = path.partition("/")
    if head == "mcdn":
        return HEADER_FOLDER.get(os.path.splitext(name)[0])
    return head if head in FOLDERS else None


def folder_cycles(edges):
    """The folders that reach each other through includes (each strongly connected
    component of more than one folder), each with one shortest cycle through its first."""
    index, low, stack, on_stack, components = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(edges.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                components.append(sorted(component))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    cycles = []
    for component in components:
        # A shortest way round from the component's first folder back to it.
        start, inside = component[0], set(component)
        paths = {start: [start]}
        frontier = [start]
        found = None
        while frontier and not found:
            following = []
            for v in frontier:
                for w in sorted(edges.get(v, ())):
                    if w == start:
                        found = paths[v] + [start]
                        break
                    if w in inside and w not in paths:
                        paths[w] = paths[v] + [w]
                        following.append(w)
                if found:
                    break
            frontier = following
        cycles.append((component, found))
    return cycles


def main():
    root = sys.argv[1] if len(sys.argv) > 1 else os.path.join(os.path.dirname(__file__), "..", "..")
    lib = os.path.join(root, "lib")
    add_stage_folders(lib)
    problems, unknown = [], []
    edges, because = {}, {}
    for base, dirs, files in os.walk(lib):
        for f in sorted(files):
            if not f.endswith((".h", ".cpp")):
                continue
            path = os.path.join(base, f)
            rel = os.path.relpath(path, lib)
            parts = rel.split(os.sep)
            if parts[0] == "include":
                layer = HEADERS.get(os.path.splitext(f)[0])
                folder = HEADER_FOLDER.get(os.path.splitext(f)[0])
            else:
                layer = FOLDERS.get(parts[1])
                folder = parts[1]
            if layer is None:
                unknown.append(rel)
                continue
            text = open(path, encoding="utf-8").read()
            for included in INCLUDE.findall(text):
                target = layer_of_include(included)
                if target is not None and target > layer:
                    problems.append("%s (layer %d) includes %s (layer %d)" %
                                    (rel, layer, included, target))
                other = folder_of_include(included)
                if other is not None and other != folder:
                    edges.setdefault(folder, set()).add(other)
                    because.setdefault((folder, other), "%s includes %s" % (rel, included))
    for folders, cycle in folder_cycles(edges):
        steps = ["%s -> %s (%s)" % (a, b, because[(a, b)]) for a, b in zip(cycle, cycle[1:])]
        problems.append("folders %s include each other, e.g. %s"
                        % (", ".join(folders), "; ".join(steps)))
    for rel in unknown:
        problems.append("%s: in no layer (a public header not named after a folder: add it to HEADERS in tests/layers/check_layers.py)" % rel)
    for p in problems:
        print("layers: " + p)
    print("layers: %d problem(s)" % len(problems))
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
