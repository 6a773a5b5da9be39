#!/usr/bin/env python3
"""Writes the MPI equivalence scenes (tests/mpi/*.json); deterministic (fixed seed)."""
import json, random, math

def lj_box(method, name):
    rnd = random.Random(7)
    n1, a = 6, 1.2                       # 6x6x6 = 216 particles on a cubic lattice
    L = n1 * a
    parts = []
    for i in range(n1):
        for j in range(n1):
            for k in range(n1):
                x = [(i + 0.5) * a, (j + 0.5) * a, (k + 0.5) * a]
                x = [c + rnd.uniform(-0.05, 0.05) for c in x]
                v = [rnd.uniform(-1, 1) for _ in range(3)]
                parts.append({"x": [round(c, 6) for c in x], "v": [round(c, 6) for c in v]})
    return {"psys": 1, "dim": 3, "integrator": "verlet", "dt": 0.002, "steps": 20,
            "box": {"lo": [0, 0, 0], "hi": [L, L, L], "periodic": [True, True, True]},
            "particles": parts,
            "forces": [{"type": "pair", "law": "lennard-jones", "epsilon": 1, "sigma": 1, "cutoff": 2.5,
                        "method": method}]}

def galaxy(method):
    rnd = random.Random(11)
    parts = []
    for i in range(150):
        r = 0.1 + 2 * rnd.random()
        th = 2 * math.pi * rnd.random()
        x = [r * math.cos(th), r * math.sin(th), rnd.uniform(-0.1, 0.1)]
        vs = 0.8 / math.sqrt(r + 0.2)
        v = [-vs * math.sin(th), vs * math.cos(th), 0]
        parts.append({"x": [round(c, 6) for c in x], "v": [round(c, 6) for c in v],
                      "mass": round(0.5 + rnd.random(), 4)})
    f = {"type": "pair", "law": "gravity", "G": 0.01, "softening": 0.05, "method": method}
    if method == "barnes-hut":
        f["theta"] = 0.6
    return {"psys": 1, "dim": 3, "integrator": "verlet", "dt": 0.005, "steps": 20,
            "particles": parts, "forces": [f]}

def granular():
    # Springs (a chain of beads) and soft-repulsion grains under gravity on a
    # floor with friction: bonded, pair and contact forces together, 2-D.
    rnd = random.Random(5)
    parts = []
    for i in range(120):
        parts.append({"x": [round(0.11 * (i % 15) + rnd.uniform(-0.01, 0.01), 6),
                            round(0.11 * (i // 15) + 0.06, 6)], "mass": 0.01})
    chain = [{"id": "c%d" % i, "x": [round(-0.5 + 0.1 * i, 6), 1.2], "mass": 0.01} for i in range(20)]
    parts += chain
    forces = [{"type": "gravity"}, {"type": "drag", "kd": 0.001},
              {"type": "pair", "law": "soft-repulsion", "k": 50, "radius": 0.1}]
    for i in range(19):
        forces.append({"type": "spring", "a": "c%d" % i, "b": "c%d" % (i + 1), "ks": 20, "kd": 0.01})
    return {"psys": 1, "dim": 2, "integrator": "rk4", "dt": 0.001, "steps": 24,
            "particles": parts, "forces": forces,
            "planes": [{"point": [0, 0], "normal": [0, 1], "restitution": 0.3, "friction": 0.2}]}

def lj_melt():
    # The LAMMPS melt at 2,048 atoms (fcc, density 0.8442, T about 3), long
    # enough that particles migrate between slabs many times: on 2 and 4
    # ranks each holds a slab and ghosts of a part of the box only.
    rnd = random.Random(13)
    nc, a = 8, (4 / 0.8442) ** (1 / 3)
    L = nc * a
    basis = [(0, 0, 0), (0.5, 0.5, 0), (0.5, 0, 0.5), (0, 0.5, 0.5)]
    parts = []
    for i in range(nc):
        for j in range(nc):
            for k in range(nc):
                for b in basis:
                    x = [(i + b[0] + 0.25) * a, (j + b[1] + 0.25) * a, (k + b[2] + 0.25) * a]
                    v = [rnd.gauss(0, math.sqrt(3.0)) for _ in range(3)]
                    parts.append({"x": [round(c, 6) for c in x], "v": [round(c, 6) for c in v]})
    return {"psys": 1, "dim": 3, "integrator": "verlet", "dt": 0.005, "steps": 60,
            "box": {"lo": [0, 0, 0], "hi": [L, L, L], "periodic": [True, True, True]},
            "particles": parts,
            "forces": [{"type": "pair", "law": "lennard-jones", "epsilon": 1, "sigma": 1, "cutoff": 2.5,
                        "method": "grid", "skin": 0.3}]}

def gas2d():
    # Free space, 2-D: soft-repulsion grains with gravity and drag, no box,
    # so the slabs are cut along the particles' extent and re-cut as it grows.
    rnd = random.Random(17)
    parts = []
    for i in range(1600):
        x = [round(0.05 * (i % 80) + rnd.uniform(-0.01, 0.01), 6), round(0.05 * (i // 80) + rnd.uniform(-0.01, 0.01), 6)]
        v = [round(rnd.uniform(-0.5, 0.5), 6), round(rnd.uniform(-0.5, 0.5), 6)]
        parts.append({"x": x, "v": v, "mass": round(0.5 + rnd.random(), 4)})
    return {"psys": 1, "dim": 2, "integrator": "rk4", "dt": 0.002, "steps": 60,
            "particles": parts,
            "forces": [{"type": "gravity", "g": [0, -1]}, {"type": "drag", "kd": 0.01},
                       {"type": "pair", "law": "soft-repulsion", "k": 200, "radius": 0.06, "method": "grid",
                        "skin": 0.01}]}

def cloth():
    # Bonded forces across ranks: a 24x24 cloth (structural, shear and bend
    # springs) pinned at two corners, a chain of muscles hanging from it,
    # gravity and drag, free 3-D space. Nothing migrates (no pair forces);
    # every spring across a cut is computed by one rank and its force sent.
    parts = [{"id": "hook", "x": [0.6, -0.3, 0.0], "fixed": True}]
    structs = [{"type": "cloth", "id": "sheet", "origin": [0, 0, 0], "size": [24, 24], "spacing": 0.05,
                "axes": [[1, 0, 0], [0, 0.6, 0.8]], "mass": 0.01, "ks": 800, "kd": 0.3, "bend_ks": 60,
                "pin": [[0, 0], [23, 0]]},
               {"type": "chain", "id": "rope", "from": [0.6, -0.35, 0], "to": [0.6, -1.2, 0.1], "count": 12,
                "mass": 0.02, "ks": 300, "kd": 0.1,
                "muscle": {"amplitude": 0.2, "omega": 9, "phase_step": -0.5}}]
    forces = [{"type": "gravity", "g": [0, 0, -9.81]},
              {"type": "spring", "a": "hook", "b": "rope[0]", "ks": 500, "kd": 0.2},
              {"type": "drag", "kd": 0.002}]
    return {"psys": 1, "dim": 3, "integrator": "rk4", "dt": 0.001, "steps": 40,
            "particles": parts, "structures": structs, "forces": forces}

def cloth_shuffled():
    # A 28x28 sheet whose particles are numbered at random (4,426 springs, no
    # runs in that numbering): the spring set takes an internal order
    # (src/forces/spring.c), which every rank must find as the serial run does.
    rnd = random.Random(5)
    n = 28
    ids = list(range(n * n))        # cell -> particle
    rnd.shuffle(ids)
    cell = [0] * (n * n)
    for c, q in enumerate(ids):
        cell[q] = c
    h = 0.05
    parts = []
    for q in range(n * n):
        c = cell[q]
        p = {"x": [round(h * (c % n), 6), 0.0, round(-h * (c // n), 6)], "mass": 0.01}
        if c in (0, n - 1):
            p["fixed"] = True
        parts.append(p)
    forces = [{"type": "gravity", "g": [0, 0, -9.81]}]
    for r in range(n):
        for col in range(n):
            for dx, dy, ks in ((1, 0, 800), (0, 1, 800), (1, 1, 800), (-1, 1, 800), (2, 0, 60), (0, 2, 60)):
                if 0 <= col + dx < n and r + dy < n:
                    forces.append({"type": "spring", "a": ids[r * n + col], "b": ids[(r + dy) * n + col + dx],
                                   "ks": ks, "kd": 0.3})
    return {"psys": 1, "dim": 3, "integrator": "rk4", "dt": 0.001, "steps": 40,
            "particles": parts, "forces": forces}

def polymer():
    # Bead-spring chains in a hot Lennard-Jones droplet in free space: pair
    # forces with migrations and springs across ranks together.
    rnd = random.Random(23)
    parts, forces = [], []
    nchain, beads, b = 216, 8, 0.95
    # each chain a random walk of steps b from a point of a 6x6x6 lattice,
    # no bead closer than 0.8 to another, so the chains cross every cut
    cells = {}

    def free(x):
        c = [int(math.floor(q)) for q in x]
        return all(sum((x[q] - p[q]) ** 2 for q in range(3)) > 0.8 ** 2
                   for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1)
                   for p in cells.get((c[0] + i, c[1] + j, c[2] + k), []))
    def walk(o):
        chain = []
        for k in range(beads):
            for _ in range(200):
                if k == 0:
                    cand = [q + rnd.uniform(-1, 1) for q in o]
                else:
                    u = [rnd.gauss(0, 1) for _ in range(3)]
                    nu = math.sqrt(sum(q * q for q in u))
                    cand = [chain[-1][q] + b * u[q] / nu for q in range(3)]
                cand = [round(q, 6) for q in cand]
                if free(cand) and all(sum((cand[q] - p[q]) ** 2 for q in range(3)) > 0.8 ** 2 for p in chain):
                    chain.append(cand)
                    break
            else:
                return None
        return chain
    for c in range(nchain):
        o = [(c % 6) * 2.4, ((c // 6) % 6) * 2.4, (c // 36) * 2.4]
        for _ in range(1000):
            chain = walk(o)
            if chain:
                break
        else:
            raise SystemExit("polymer: no room for chain %d" % c)
        for k, x in enumerate(chain):
            cells.setdefault(tuple(int(math.floor(q)) for q in x), []).append(x)
            v = [round(rnd.gauss(0, 1.2), 6) for _ in range(3)]
            parts.append({"id": "p%d.%d" % (c, k), "x": x, "v": v})
        for k in range(beads - 1):
            forces.append({"type": "spring", "a": "p%d.%d" % (c, k), "b": "p%d.%d" % (c, k + 1), "ks": 100,
                           "kd": 0.5, "rest": b})
    forces.append({"type": "pair", "law": "lennard-jones", "epsilon": 1, "sigma": 0.8, "cutoff": 2.0,
                   "method": "grid", "skin": 0.2})
    return {"psys": 1, "dim": 3, "integrator": "verlet", "dt": 0.002, "steps": 50,
            "particles": parts, "forces": forces}

def arm():
    # Behaviour functions across ranks (notes section 6): 2-D chains held by
    # distance and angle behaviours, one end of each on a circle
    # (point-on-sphere), under gravity, with a spring between neighbours;
    # the chains slant, so that every cut crosses some.
    parts, forces = [], []
    for c in range(10):
        for k in range(12):
            parts.append({"id": "a%d.%d" % (c, k), "x": [round(0.3 * c + 0.06 * k, 6), round(-0.11 * k, 6)],
                          "mass": 0.05})
        for k in range(11):
            forces.append({"type": "behavior", "function": "distance", "particles": ["a%d.%d" % (c, k), "a%d.%d" % (c, k + 1)],
                           "ks": 400, "kd": 2})
        for k in range(10):
            forces.append({"type": "behavior", "function": "angle",
                           "particles": ["a%d.%d" % (c, k), "a%d.%d" % (c, k + 1), "a%d.%d" % (c, k + 2)],
                           "ks": 3, "kd": 0.05})
        forces.append({"type": "behavior", "function": "point-on-sphere", "particles": ["a%d.0" % c],
                       "center": [round(0.3 * c, 6), 0.1], "radius": 0.1, "ks": 200, "kd": 1})
        if c:
            forces.append({"type": "spring", "a": "a%d.11" % (c - 1), "b": "a%d.11" % c, "ks": 5, "kd": 0.01})
    forces.insert(0, {"type": "gravity", "g": [0, -9.81]})
    return {"psys": 1, "dim": 2, "integrator": "rk4", "dt": 0.002, "steps": 40,
            "particles": parts, "forces": forces}

def crank():
    # Controlled particles across ranks: 12 ropes of 16 beads hang from
    # driven ends (circles, oscillations, keyframes); soft repulsion between
    # all beads (so they migrate), gravity, drag, 2-D, free space.
    parts, forces = [], [{"type": "gravity", "g": [0, -9.81]}, {"type": "drag", "kd": 0.01}]
    kinds = ["circle", "oscillate", "keyframes"]
    for r in range(12):
        x0 = 0.35 * r
        kind = kinds[r % 3]
        if kind == "circle":
            ctl = {"type": "circle", "center": [x0, 0.05], "radius": 0.05, "omega": 9 + r, "phase": 0.4 * r}
        elif kind == "oscillate":
            ctl = {"type": "oscillate", "center": [x0, 0], "direction": [1, 0.3], "amplitude": 0.08, "omega": 7.0}
        else:
            ctl = {"type": "keyframes", "frames": [[0, x0, 0], [0.03, x0 + 0.1, 0.02], [0.06, x0 - 0.05, 0], [1, x0, 0]]}
        # the controller's position at t = 0
        x_start = {"circle": [round(x0 + 0.05 * math.cos(0.4 * r), 6), round(0.05 + 0.05 * math.sin(0.4 * r), 6)],
                   "oscillate": [x0, 0], "keyframes": [x0, 0]}[kind]
        parts.append({"id": "top%d" % r, "x": x_start, "control": ctl})
        for k in range(1, 16):
            parts.append({"id": "r%d.%d" % (r, k), "x": [round(x0 + 0.03 * k, 6), round(-0.07 * k, 6)], "mass": 0.02})
        for k in range(16 - 1):
            a = "top%d" % r if k == 0 else "r%d.%d" % (r, k)
            forces.append({"type": "spring", "a": a, "b": "r%d.%d" % (r, k + 1), "ks": 300, "kd": 0.2})
    forces.append({"type": "pair", "law": "soft-repulsion", "k": 100, "radius": 0.05, "method": "grid", "skin": 0.01})
    return {"psys": 1, "dim": 2, "integrator": "rk4", "dt": 0.001, "steps": 40,
            "particles": parts, "forces": forces}

def hail():
    # Contact events across ranks: 300 grains and a 12-bead chain thrown
    # down onto a floor (restitution, friction) between two walls, soft
    # repulsion between all, gravity, 2-D. Grains hit the planes from the
    # first steps on, on every rank, and migrate.
    rnd = random.Random(29)
    parts, forces = [], [{"type": "gravity", "g": [0, -9.81]}]
    for i in range(300):
        x = [round(0.03 + 0.065 * (i % 20) + rnd.uniform(-0.01, 0.01), 6),
             round(0.02 + 0.065 * (i // 20) + rnd.uniform(-0.005, 0.005), 6)]
        v = [round(rnd.uniform(-1, 1), 6), round(rnd.uniform(-3, -1), 6)]
        parts.append({"x": x, "v": v, "mass": round(0.5 + rnd.random(), 4)})
    for k in range(12):
        parts.append({"id": "c%d" % k, "x": [round(0.1 + 0.1 * k, 6), round(1.4 - 0.1 * k, 6) + 0.0325], "v": [0, -2],
                      "mass": 0.5})  # a diagonal between the grains' rows: every cut crosses it
        if k:
            forces.append({"type": "spring", "a": "c%d" % (k - 1), "b": "c%d" % k, "ks": 400, "kd": 0.5})
    forces.append({"type": "pair", "law": "soft-repulsion", "k": 300, "radius": 0.05, "method": "grid", "skin": 0.01})
    planes = [{"point": [0, 0], "normal": [0, 1], "restitution": 0.6, "friction": 0.3},
              {"point": [0, 0], "normal": [1, 0], "restitution": 0.8},
              {"point": [1.33, 0], "normal": [-1, 0.05], "restitution": 0.8, "friction": 0.1}]
    return {"psys": 1, "dim": 2, "integrator": "rk4", "dt": 0.001, "steps": 40,
            "particles": parts, "forces": forces, "planes": planes}

scenes = {"lj-grid": lj_box("grid", "lj-grid"), "lj-direct": lj_box("direct", "lj-direct"),
          "gravity-direct": galaxy("direct"), "gravity-bh": galaxy("barnes-hut"), "granular": granular(),
          "lj-melt": lj_melt(), "gas2d": gas2d(),
          "cloth": cloth(), "cloth-shuffled": cloth_shuffled(), "polymer": polymer(), "arm": arm(), "crank": crank(), "hail": hail()}
for name, sc in scenes.items():
    with open(name + ".json", "w") as fp:
        json.dump(sc, fp, separators=(",", ":"))
        fp.write("\n")
