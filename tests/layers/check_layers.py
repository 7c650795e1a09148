#!/usr/bin/env python3
"""check_layers.py: the layer rules of the tree, checked (ctest `layers`).

The code stands in layers, each a folder and a CMake library (pf_<folder>)
that may use only the layers listed for it below (docs/architecture.md draws
them). This checks, and names file:line for every breach:

  1. every #include "..." in a layer's files points into the layer itself or
     into a layer it may use (no include that climbs, none across siblings);
  2. every target_link_libraries of a layer's library in its CMakeLists.txt
     names only libraries of layers it may use, and only the outside
     libraries that layer is allowed (proto/ and everything below it never
     reach Embree, libpng or cJSON, even through another layer);
  3. no circle of files: with a header and its source taken as one module,
     the include graph of the whole tree has no cycle;
  4. the sizes the house keeps (docs/architecture.md): no C file of the tree
     over 1000 lines, no function over 150 (a function starts at a line
     "{" in column 0 and ends at the next "}" in column 0).

bench/ and fuzz/ are tools above the libraries: they may use any layer but
the two programs (coordinator/, worker/). tests/ may include anything.

usage: check_layers.py [ROOT]      (default: the repository this file is in)
       check_layers.py --stats [ROOT] (C lines per folder and their share,
                                    the longest files and functions)
       check_layers.py --self-test (plants bad includes, links and a circle
                                    in a copy of the tree; each must fail)
Exit status 0 when the tree keeps the rules, 1 with one line per breach.
"""
import os
import re
import shutil
import subprocess
import sys
import tempfile

# Each layer and the layers it may use (directly; the list is closed under
# "below": a layer may use everything below it that it names).
LAYERS = {
    "base": [],
    "image": ["base"],
    "scene": ["image", "base"],
    "mesh": ["scene", "image", "base"],
    "load": ["mesh", "scene", "image", "base"],
    "accel": ["scene", "image", "base"],
    "material": ["scene", "image", "base"],
    "light": ["scene", "image", "base"],
    "proto": ["scene", "base"],
    "photon": ["accel", "material", "light", "scene", "image", "base"],
    "render": ["photon", "proto", "accel", "material", "light", "scene", "image", "base"],
    "worker": ["render", "photon", "proto", "accel", "material", "light", "scene", "image", "base"],
    "coordinator": ["render", "load", "mesh", "photon", "proto", "accel", "material", "light", "scene",
                    "image", "base"],
}
# Tool folders: what they may not use.
TOOLS = {"bench": ["coordinator", "worker"], "fuzz": ["coordinator", "worker"]}
# Outside libraries each layer's CMake library may link (as spelled in the
# CMakeLists.txt files).
EXTERNAL = {
    "base": {"m"},
    "image": {"PkgConfig::PNG", "tinyexr::tinyexr", "PkgConfig::STB"},
    "mesh": {"PkgConfig::ZLIB"},
    "load": {"PkgConfig::CJSON"},
    "accel": {"embree"},
    "photon": {"OpenMP::OpenMP_C"},
    "render": {"OpenMP::OpenMP_C"},
    "worker": {"PkgConfig::ZMQ", "Threads::Threads"},
    "coordinator": {"PkgConfig::ZMQ", "Threads::Threads"},
}
# Outside libraries that proto/ and the layers it stands on must never reach.
PROTO_NEVER = {"embree", "PkgConfig::PNG", "PkgConfig::CJSON"}

INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"')
SOURCE = (".c", ".h")


def source_files(root, folder):
    out = []
    for dirpath, dirnames, filenames in os.walk(os.path.join(root, folder)):
        dirnames[:] = sorted(d for d in dirnames if not d.startswith("build"))
        for f in sorted(filenames):
            if f.endswith(SOURCE):
                out.append(os.path.relpath(os.path.join(dirpath, f), root))
    return out


def includes(root, path):
    """(line number, included path) for every quoted include of path."""
    with open(os.path.join(root, path), encoding="utf-8", errors="replace") as f:
        for n, line in enumerate(f, 1):
            m = INCLUDE.match(line)
            if m:
                yield n, m.group(1)


def s_may_use(layer):
    allowed = LAYERS[layer]
    return "no other layer" if not allowed else "only " + ", ".join(f"{a}/" for a in allowed)


def check_includes(root):
    bad = []
    for layer, allowed in list(LAYERS.items()) + [(t, None) for t in TOOLS]:
        for path in source_files(root, layer):
            for n, inc in includes(root, path):
                target = inc.split("/", 1)[0] if "/" in inc else layer
                if target == layer:
                    continue
                if allowed is None:  # a tool folder
                    if target in TOOLS[layer]:
                        bad.append(f"{path}:{n}: includes {inc}: {layer}/ may not use {target}/")
                    continue
                if target not in LAYERS:
                    bad.append(f"{path}:{n}: includes {inc}, which is in no layer")
                elif target not in allowed:
                    bad.append(f"{path}:{n}: includes {inc}: layer {layer}/ may use {s_may_use(layer)}")
    return bad


LINK = re.compile(r"target_link_libraries\s*\(\s*(\S+)\s+(?:PUBLIC|PRIVATE|INTERFACE)?([^)]*)\)", re.S)


def cmake_links(root, layer):
    """(line, target, [libraries]) for each target_link_libraries of layer's CMakeLists.txt."""
    path = os.path.join(root, layer, "CMakeLists.txt")
    if not os.path.exists(path):
        return []
    text = open(path, encoding="utf-8").read()
    out = []
    for m in LINK.finditer(text):
        line = text.count("\n", 0, m.start()) + 1
        libs = [w for w in m.group(2).split() if w not in ("PUBLIC", "PRIVATE", "INTERFACE")]
        out.append((line, m.group(1), libs))
    return out


def check_links(root):
    bad = []
    reach = {}  # layer -> outside libraries its library links, with everything it links
    graph = {}
    for layer in LAYERS:
        graph[layer] = set()
        ext = set()
        for line, target, libs in cmake_links(root, layer):
            lib_of_layer = target == f"pf_{layer}"
            for lib in libs:
                if lib.startswith("pf_"):
                    dep = lib[3:]
                    if dep != layer and dep not in LAYERS[layer]:
                        bad.append(f"{layer}/CMakeLists.txt:{line}: {target} links {lib}: layer {layer}/ may use "
                                   f"{s_may_use(layer)}")
                    if lib_of_layer:
                        graph[layer].add(dep)
                else:
                    if lib not in EXTERNAL.get(layer, set()):
                        bad.append(f"{layer}/CMakeLists.txt:{line}: {target} links {lib}, which layer {layer}/ "
                                   f"may not link (allowed: {', '.join(sorted(EXTERNAL.get(layer, []))) or 'none'})")
                    if lib_of_layer:
                        ext.add(lib)
        reach[layer] = ext

    def closure(layer, seen):
        if layer in seen:
            return set()
        seen.add(layer)
        out = set(reach.get(layer, set()))
        for dep in graph.get(layer, ()):
            out |= closure(dep, seen)
        return out

    for layer in ["proto"] + [l for l in LAYERS if l in LAYERS["proto"]]:
        leaked = closure(layer, set()) & PROTO_NEVER
        if leaked:
            bad.append(f"{layer}/CMakeLists.txt: pf_{layer} reaches {', '.join(sorted(leaked))}: proto/ and the "
                       f"layers under it must not link Embree, libpng or cJSON")
    return bad


def module(path):
    return os.path.splitext(path)[0]


def check_circles(root):
    """Cycles of the include graph between modules (x.h and x.c as one)."""
    files = []
    for folder in list(LAYERS) + list(TOOLS):
        files += source_files(root, folder)
    known = {module(f) for f in files}
    edges = {}
    where = {}
    for f in files:
        a = module(f)
        for n, inc in includes(root, f):
            b = module(inc if "/" in inc else os.path.join(os.path.dirname(f), inc))
            if b != a and b in known:
                edges.setdefault(a, set()).add(b)
                where.setdefault((a, b), f"{f}:{n}")
    # Tarjan's strongly connected components, iteratively.
    index, low, on, stack, comps, counter = {}, {}, set(), [], [], [0]
    for start in sorted(known):
        if start in index:
            continue
        work = [(start, iter(sorted(edges.get(start, ()))))]
        index[start] = low[start] = counter[0]
        counter[0] += 1
        stack.append(start)
        on.add(start)
        while work:
            v, it = work[-1]
            advanced = False
            for w in it:
                if w not in index:
                    index[w] = low[w] = counter[0]
                    counter[0] += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(edges.get(w, ())))))
                    advanced = True
                    break
                if w in on:
                    low[v] = min(low[v], index[w])
            if advanced:
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = []
                while True:
                    w = stack.pop()
                    on.discard(w)
                    comp.append(w)
                    if w == v:
                        break
                if len(comp) > 1:
                    comps.append(sorted(comp))
    bad = []
    for comp in comps:
        ties = [where[(a, b)] for a in comp for b in sorted(edges.get(a, ())) if b in comp]
        bad.append(f"circle of files: {' <-> '.join(comp)} (includes at {', '.join(ties)})")
    return bad


MAX_FILE_LINES = 1000
MAX_FUNCTION_LINES = 150


def all_c_files(root):
    out = []
    for dirpath, dirnames, filenames in os.walk(root):
        dirnames[:] = sorted(d for d in dirnames if not d.startswith(("build", ".")))
        for f in sorted(filenames):
            if f.endswith(SOURCE):
                out.append(os.path.relpath(os.path.join(dirpath, f), root))
    return out


def functions(root, path):
    """(first line, length, signature) of each function body of path."""
    lines = open(os.path.join(root, path), encoding="utf-8", errors="replace").read().split("\n")
    start = None
    for i, line in enumerate(lines):
        if line.startswith("{") and start is None:
            j = i - 1
            while j > 0 and lines[j - 1].strip() and not lines[j - 1].rstrip().endswith((";", "}", "*/")) \
                    and not lines[j - 1].startswith("#"):
                j -= 1
            start = (i, lines[j].strip() if j >= 0 else "")
        elif line.startswith("}") and start is not None:
            yield start[0] + 1, i - start[0] + 1, start[1]
            start = None


def check_sizes(root):
    bad = []
    for path in all_c_files(root):
        n = sum(1 for _ in open(os.path.join(root, path), encoding="utf-8", errors="replace"))
        if n > MAX_FILE_LINES:
            bad.append(f"{path}: {n} lines, over {MAX_FILE_LINES}: split it by idea")
        for line, length, sig in functions(root, path):
            if length > MAX_FUNCTION_LINES:
                bad.append(f"{path}:{line}: a function of {length} lines, over {MAX_FUNCTION_LINES} "
                           f"({sig[:60]}): split it into named steps")
    return bad


def stats(root):
    per, total, files, funcs = {}, 0, [], []
    for path in all_c_files(root):
        n = sum(1 for _ in open(os.path.join(root, path), encoding="utf-8", errors="replace"))
        folder = os.path.dirname(path) or "."
        per[folder] = per.get(folder, 0) + n
        total += n
        files.append((n, path))
        funcs += [(length, f"{path}:{line}") for line, length, _ in functions(root, path)]
    print(f"{total} lines of C in {len(files)} files")
    for folder, n in sorted(per.items(), key=lambda kv: -kv[1])[:6]:
        print(f"  folder {folder + '/':22s} {n:6d} lines  {100.0 * n / total:5.1f} %")
    for n, path in sorted(files, reverse=True)[:3]:
        print(f"  file {path}: {n} lines")
    for n, where in sorted(funcs, reverse=True)[:3]:
        print(f"  function at {where}: {n} lines")


def check(root):
    return check_includes(root) + check_links(root) + check_circles(root) + check_sizes(root)


def self_test():
    """Plants one breach of each kind in a copy of the tree; each must be caught, naming where."""
    here = os.path.dirname(os.path.abspath(__file__))
    root = os.path.abspath(os.path.join(here, "..", ".."))
    failures = 0
    plants = [
        ("base/vec.h", '#include "render/render.h"\n', "base/vec.h:", "an include that climbs"),
        ("load/obj.c", '#include "accel/accel.h"\n', "load/obj.c:", "an include across siblings"),
        ("proto/CMakeLists.txt", "target_link_libraries(pf_proto PUBLIC pf_photon)\n", "proto/CMakeLists.txt:",
         "a link that climbs"),
        ("scene/CMakeLists.txt", "target_link_libraries(pf_scene PUBLIC embree)\n", "scene/CMakeLists.txt:",
         "Embree under proto"),
        ("scene/camera.h", '#include "scene/scene.h"\n#include "scene/camera_extra.h"\n', "circle of files",
         "a circle of files"),
        ("base/hash.c", "void pf_long(void)\n{\n" + "    ;\n" * 150 + "}\n", "base/hash.c:", "a function over 150 lines"),
    ]
    for path, text, expect, what in plants:
        with tempfile.TemporaryDirectory() as tmp:
            for folder in list(LAYERS) + list(TOOLS):
                src = os.path.join(root, folder)
                if os.path.isdir(src):
                    shutil.copytree(src, os.path.join(tmp, folder),
                                    ignore=shutil.ignore_patterns("build*", "*.o"))
            clean = check(tmp)
            with open(os.path.join(tmp, path), "a", encoding="utf-8") as f:
                f.write(text)
            if what == "a circle of files":
                with open(os.path.join(tmp, "scene", "camera_extra.h"), "w", encoding="utf-8") as f:
                    f.write('#include "scene/camera.h"\n')
            found = [b for b in check(tmp) if b not in clean]
            ok = any(expect in b for b in found)
            print(f"{'ok  ' if ok else 'FAIL'}  {what} ({path}) caught: {found[0] if found else 'nothing reported'}")
            failures += not ok
    return failures


def main():
    if len(sys.argv) > 1 and sys.argv[1] == "--stats":
        stats(sys.argv[2] if len(sys.argv) > 2 else os.path.abspath(
            os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")))
        return 0
    if len(sys.argv) > 1 and sys.argv[1] == "--self-test":
        failures = self_test()
        print(f"{6 - failures} passed, {failures} failed")
        return 1 if failures else 0
    root = sys.argv[1] if len(sys.argv) > 1 else os.path.abspath(
        os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
    bad = check(root)
    for b in bad:
        print(b)
    nfiles = sum(len(source_files(root, f)) for f in list(LAYERS) + list(TOOLS))
    print(f"layers: {nfiles} files in {len(LAYERS)} layers and {len(TOOLS)} tool folders, "
          f"{len(bad)} breach{'es' if len(bad) != 1 else ''}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
