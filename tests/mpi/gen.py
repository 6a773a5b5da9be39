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

scenes = {"lj-grid": lj_box("grid", "lj-grid"), "lj-direct": lj_box("direct", "lj-direct"),
          "gravity-direct": galaxy("direct"), "gravity-bh": galaxy("barnes-hut"), "granular": granular(),
          "lj-melt": lj_melt(), "gas2d": gas2d()}
for name, sc in scenes.items():
    with open(name + ".json", "w") as fp:
        json.dump(sc, fp, separators=(",", ":"))
        fp.write("\n")
