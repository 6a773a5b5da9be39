#!/usr/bin/env python3
"""The library's layers point one way (docs/architecture.md).

    layers.py SRCDIR OBJDIR
    layers.py SRCDIR --objects "OBJ;OBJ;..."

SRCDIR is the repository's src/ folder; OBJDIR the folder holding the
library's compiled objects (CMake's CMakeFiles/psys.dir), or --objects the
list of them (CMake's $<TARGET_OBJECTS:psys>, so stale objects of files
that no longer exist are not read). Three checks, each
failure named by file:

1. includes: a file of src/LAYER/ includes only headers of its own layer or
   of layers below it (and the public psys/*.h); only io/ includes cJSON;
2. uses: from the objects' symbols (nm), "file A uses a function or
   variable that file B defines" never points from a lower layer to a
   higher one, nor between two layers of the same rank, and only io/
   objects use cJSON's symbols;
3. cycles: no strongly connected group of more than four files in that
   graph (a registry and its entries may form a small one).

Exit 0 when all hold, 1 with the violations listed, 2 on bad usage.
"""
import collections
import os
import re
import subprocess
import sys

# Lowest first. A layer may use any layer of a lower rank; layers of the
# same rank know nothing of each other.
RANK = {
    "base": 0,     # errors, allocation, OpenMP and CPU-dispatch macros
    "solvers": 1,  # the ODE interface's solvers and the Jacobian sink (numerics)
    "core": 2,     # the particle system's storage: particles, force list, controllers, planes
    "pair": 3,     # neighbour grids and Barnes-Hut trees of pair forces
    "forces": 4,   # one file per force type: physics only; the box and charges
    "fast": 5,     # the fused one-sweep derivative and the springs' state order
    "sim": 6,      # the system as an ODE, the step loop, structures, drawing
    "mpi": 7,      # a run spread over MPI ranks (-DPSYS_MPI=ON builds)
    "io": 8,       # scene JSON, runs, output files
}
MAX_CYCLE = 4
INCLUDE = re.compile(r'^\s*#\s*include\s*([<"])([^>"]+)[>"]', re.M)


def layer_of(rel):
    """Layer of a path relative to src/ ("core/system.c" -> "core"), or None."""
    parts = rel.split("/")
    return parts[0] if len(parts) > 1 and parts[0] in RANK else None


def may_use(user, owner):
    return user == owner or RANK[user] > RANK[owner]


def check_includes(src, problems):
    for root, _, files in os.walk(src):
        for name in sorted(files):
            if not name.endswith((".c", ".h")):
                continue
            path = os.path.join(root, name)
            rel = os.path.relpath(path, src)
            layer = layer_of(rel)
            if layer is None:
                problems.append(f"src/{rel}: not in a layer folder ({', '.join(RANK)})")
                continue
            with open(path, encoding="utf-8") as fp:
                text = fp.read()
            for kind, inc in INCLUDE.findall(text):
                if "cjson" in inc.lower() and layer != "io":
                    problems.append(f"src/{rel}: includes {inc} (only io/ may use cJSON)")
                if kind != '"' or inc.startswith("psys/"):
                    continue
                target = inc if "/" in inc else os.path.join(os.path.dirname(rel), inc)
                tlayer = layer_of(os.path.normpath(target))
                if tlayer is None:
                    problems.append(f"src/{rel}: includes \"{inc}\", which is in no layer")
                elif not may_use(layer, tlayer):
                    problems.append(f"src/{rel}: includes \"{inc}\" ({layer} may not use {tlayer})")


def objects(objdir):
    if isinstance(objdir, list):
        paths = objdir
    else:
        paths = [os.path.join(root, name) for root, _, files in os.walk(objdir) for name in files]
    out = []
    for path in paths:
        if not path.endswith(".o"):
            continue
        # CMake names objects after their source: .../psys.dir/src/core/system.c.o
        norm = path.replace(os.sep, "/")
        rel = norm.split("/src/", 1)[1] if "/src/" in norm else os.path.basename(norm)
        out.append((rel[:-4] if rel.endswith(".c.o") else rel, path))
    return sorted(out)


def symbols(path):
    res = subprocess.run(["nm", "-P", path], capture_output=True, text=True, check=True)
    defined, used = set(), set()
    for line in res.stdout.splitlines():
        f = line.split()
        if len(f) < 2:
            continue
        sym, typ = f[0], f[1]
        if typ == "U":
            used.add(sym)
        elif typ in "TDBRCVWGS":
            defined.add(sym)
    return defined, used


def strongly_connected(graph):
    """Tarjan's algorithm, iterative; returns the components."""
    index, low, stack, on, comps, counter = {}, {}, [], set(), [], [0]
    for v0 in sorted(graph):
        if v0 in index:
            continue
        work = [(v0, iter(sorted(graph[v0])))]
        index[v0] = low[v0] = counter[0]
        counter[0] += 1
        stack.append(v0)
        on.add(v0)
        while work:
            v, it = work[-1]
            for w in it:
                if w not in index:
                    index[w] = low[w] = counter[0]
                    counter[0] += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(graph[w]))))
                    break
                if w in on:
                    low[v] = min(low[v], index[w])
            else:
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
                    comps.append(sorted(comp))
    return comps


def check_uses(objdir, problems):
    objs = objects(objdir)
    if not objs:
        problems.append(f"{objdir}: no objects found (build the library first)")
        return 0
    owner, uses = {}, {}
    for rel, path in objs:
        defined, used = symbols(path)
        for s in defined:
            owner[s] = rel
        uses[rel] = used
    graph = collections.defaultdict(set)
    for rel, used in uses.items():
        graph[rel]
        layer = layer_of(rel)
        if layer is None:
            problems.append(f"src/{rel}.c: not in a layer folder")
            continue
        for s in sorted(used):
            if s.startswith("cJSON") and layer != "io":
                problems.append(f"src/{rel}.c uses {s} (only io/ may use cJSON)")
            b = owner.get(s)
            if b is None or b == rel:
                continue
            graph[rel].add(b)
            blayer = layer_of(b)
            if blayer is not None and not may_use(layer, blayer):
                problems.append(f"src/{rel}.c uses {s}, defined in src/{b}.c ({layer} may not use {blayer})")
    for comp in strongly_connected(graph):
        if len(comp) > MAX_CYCLE:
            problems.append(f"a cycle of {len(comp)} files: " + ", ".join(f"src/{c}.c" for c in comp))
    return len(objs)


def main(argv):
    if len(argv) == 4 and argv[2] == "--objects":
        src, objdir = argv[1], [p for p in argv[3].split(";") if p]
    elif len(argv) == 3:
        src, objdir = argv[1], argv[2]
    else:
        print("usage: layers.py SRCDIR (OBJDIR | --objects 'OBJ;OBJ;...')", file=sys.stderr)
        return 2
    problems = []
    check_includes(src, problems)
    n = check_uses(objdir, problems)
    for p in problems:
        print("layers:", p)
    if problems:
        print(f"layers: {len(problems)} violation(s)")
        return 1
    print(f"layers: {n} objects, every include and use points down the layers, no cycle over {MAX_CYCLE} files")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
