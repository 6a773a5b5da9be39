#!/usr/bin/env python3
"""Runs the benchmarks behind bench/README.md's Results and prints them.

    python3 bench/results.py [BUILD_DIR] [--logs DIR] [--skip STEP,...] [--rounds N]
    python3 bench/results.py [BUILD_DIR] --logs DIR --replay [--check FILE]   (print again from DIR)
    python3 bench/results.py [BUILD_DIR] --quick [--logs DIR]                 (tiny sizes: does it all still run?)

One command for every figure of the Results section, each peer interleaved
with psys by the script that runs it, so the ratios hold within this run:

    cloth      bench/cloth_vs_ref.sh BUILD N "100 256 1024"  (plain C reference)
    suite      BUILD/psys bench                               (every default case)
    ceiling    BUILD/spring_ceiling                           (what the 50 ns target asks)
    lj         bench/lj_vs_lammps.sh BUILD N 1                (needs lmp: apt-get install lammps)
    grid       BUILD/pair_bench grid-scaling
    bh         BUILD/pair_bench bh-crossover
    stiff      bench/stiff_cloth.sh BUILD                     (needs libbullet-dev)
    callgrind  valgrind --tool=callgrind on cloth-100 and cloth-256 (needs valgrind)

It prints the Results section as Markdown on stdout (progress on stderr)
and keeps each program's raw output in --logs (default: a new folder under
/tmp). A step whose tool is missing is left out with a note. About 20
minutes on a 2-vCPU host; run it on a quiet machine. bench/results/ keeps
the outputs behind bench/README.md's Results; the test docs.bench_results
replays them and checks that the README holds what they print (--check).
--quick runs every step at tiny sizes (cloth 8 and 16, 16×16 stiff cloth,
the small pair-force sizes, one round; about half a minute): its figures mean
nothing, but it proves that every program and script still runs and that
this file still reads what they print today (the test bench.results_quick).
The peers' sources are looked for in $PEERS (bench/README.md, "Peer programs").
"""
import argparse
import datetime
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
STEPS = ["cloth", "suite", "ceiling", "lj", "grid", "bh", "stiff", "callgrind"]
PEERS = os.environ.get("PEERS", os.path.join(ROOT, "bench", "peers"))


def log(msg):
    print(f"results.py: {msg}", file=sys.stderr, flush=True)


def read(path):
    with open(path, encoding="utf-8") as f:
        return f.read()


def run(a, name, cmd, env=None):
    """Runs cmd in the source tree; its stdout, also kept as a.logs/name.log
    (with --replay, that file's text, nothing run)."""
    out = os.path.join(a.logs, f"{name}.log")
    if a.replay:
        return read(out)
    log(f"{name}: {' '.join(cmd)}")
    e = dict(os.environ, **(env or {}))
    p = subprocess.run(cmd, cwd=ROOT, env=e, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    with open(out, "w", encoding="utf-8") as f:
        f.write(p.stdout)
    if p.returncode != 0:
        raise RuntimeError(f"{name}: exit {p.returncode}; see {out}")
    return p.stdout


def jsons(text):
    out = []
    for line in text.splitlines():
        line = line.strip()
        if line.startswith("{"):
            try:
                out.append(json.loads(line.replace(": nan", ": null")))
            except json.JSONDecodeError:
                pass
    return out


def peer(a, name):
    """The path of the peer's source file name (FileNotFoundError, so the
    step is left out, where it is not there)."""
    path = os.path.abspath(os.path.join(PEERS, name))
    if not a.replay and not os.path.exists(path):
        raise FileNotFoundError(f"{name} of the peers (set PEERS)")
    return path


def groups(pattern, text):
    """The groups of pattern's first match in text (RuntimeError if none)."""
    m = re.search(pattern, text)
    if not m:
        raise RuntimeError(f"no match for {pattern!r}")
    return m.groups()


def num(pattern, text, kind=float):
    return kind(groups(pattern, text)[0])


def host():
    info = {}
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                k, _, v = line.partition(":")
                info.setdefault(k.strip(), v.strip())
    except OSError:
        pass
    caches = []
    base = "/sys/devices/system/cpu/cpu0/cache"
    for idx in sorted(os.listdir(base)) if os.path.isdir(base) else []:
        try:
            rd = lambda n: open(os.path.join(base, idx, n)).read().strip()  # noqa: E731
            if rd("type") in ("Data", "Unified") and rd("level") in ("1", "2"):
                caches.append(f"L{rd('level')} {rd('size')}")
        except OSError:
            pass
    simd = "AVX-512" if "avx512f" in info.get("flags", "") else "AVX2" if "avx2" in info.get("flags", "") else "SSE2"
    return (f"{os.cpu_count()}-vCPU {info.get('model name', 'unknown CPU')} (family {info.get('cpu family', '?')} "
            f"model {info.get('model', '?')}: {simd}, {', '.join(caches)} per core)")


def commit():
    try:
        c = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT, capture_output=True, text=True).stdout.strip()
        dirty = subprocess.run(["git", "status", "--porcelain", "--untracked-files=no"], cwd=ROOT, capture_output=True,
                               text=True).stdout.strip()
        return c + (" (with uncommitted changes)" if dirty else "")
    except OSError:
        return "unknown"


def step_cloth(a):
    sizes, secs = ("8 16", "0.02") if a.quick else ("100 256 1024", "0.4")
    t = run(a, "cloth", ["sh", "bench/cloth_vs_ref.sh", a.build, str(a.rounds), sizes],
            env={"REF_SRC": peer(a, "ref_cloth.c"), "BENCH_SECONDS": secs})
    r = {"triad": num(r"STREAM triad, 1 thread: ([0-9.]+)", t), "sizes": {}}
    for m in re.finditer(r"cloth-(\d+) rk4: psys ([0-9.]+) ns, ref_cloth ([0-9.]+) ns per particle-step; psys/ref = "
                         r"([0-9.]+); floor ([0-9.]+) ns: psys ([0-9.]+)x", t):
        r["sizes"][int(m.group(1))] = [float(x) for x in m.groups()[1:]]
    n2, p2, sp = groups(r"cloth-(\d+) rk4, 2 threads: ([0-9.]+) ns per particle-step; speed-up over 1 thread "
                        r"([0-9.]+)", t)
    r["two"] = [int(n2), float(p2), float(sp)]
    return r


def step_suite(a):
    quick = ["--reps", "1", "--seconds", "0.01"] if a.quick else []
    return {(j["case"], j["integrator"]): j for j in jsons(run(a, "suite", [f"{a.build}/psys", "bench"] + quick))}


def step_ceiling(a):
    quick = ["16", "300"] if a.quick else []
    return {j["case"]: j for j in jsons(run(a, "ceiling", [f"{a.build}/spring_ceiling"] + quick))}


def step_lj(a):
    if not a.replay and not shutil.which("lmp"):
        raise FileNotFoundError("lmp (apt-get install lammps)")
    js = jsons(run(a, "lj", ["bash", "bench/lj_vs_lammps.sh", a.build, str(a.rounds), "1"],
                   env={"PEERS": os.path.dirname(peer(a, "in.lj"))}))
    atoms = next(j["atoms"] for j in js if j["case"] == "lj-melt")
    steps = next(j["steps"] for j in js if j["case"] == "lj-melt")
    last = [j for j in js if j["case"] == "lj-melt-vs-lammps"][-1]
    ns = lambda s: s * 1e9 / (atoms * steps)  # noqa: E731
    return {"atoms": atoms, "psys": ns(last["psys_seconds"]), "lammps": ns(last["lammps_seconds"]),
            "check": ns(last["lammps_check_seconds"]), "r": last["psys_over_lammps"],
            "rc": last["psys_over_lammps_check"]}


def step_grid(a):
    quick = ["--max-n", "4000", "--steps", "2"] if a.quick else []
    return [j for j in jsons(run(a, "grid", [f"{a.build}/pair_bench", "grid-scaling"] + quick))
            if j["case"] == "grid-scaling-summary"][-1]


def step_bh(a):
    js = jsons(run(a, "bh", [f"{a.build}/pair_bench", "bh-crossover"] + (["--max-n", "1024"] if a.quick else [])))
    sizes = [j for j in js if j["case"] == "bh-crossover"]
    return {"summary": [j for j in js if j["case"] == "bh-crossover-summary"][-1], "largest": sizes[-1],
            "err": (min(j["force_error"] for j in sizes), max(j["force_error"] for j in sizes))}


def step_stiff(a):
    if not a.replay and not os.path.exists("/usr/include/bullet/btBulletDynamicsCommon.h"):
        raise FileNotFoundError("libbullet-dev")
    env = {"OMP_NUM_THREADS": "1", "PEERS": os.path.dirname(peer(a, "bullet_cloth.cpp"))}
    t = run(a, "stiff", ["bash", "bench/stiff_cloth.sh", a.build], env=dict(env, N="16", REPS="1") if a.quick else env)
    js = jsons(t)
    head = groups(r"# 4\. interleaved: bullet piterations=(\S+), implicit-euler dt=1/60 and dt=(\S+), "
                  r"rk4 dt=(\S+)", t)
    med = groups(r"# medians of (\d+): bullet ([0-9.]+) s, implicit-euler dt=1/60 ([0-9.]+) s, "
                 r"implicit-euler dt=\S+ ([0-9.]+) s", t)
    tail = t[t.index("# 4. interleaved"):]
    inter = jsons(tail)
    it, big, _rk = head
    if "none" in (it, big):
        raise RuntimeError(f"no Bullet setting or implicit-euler step reached <= 2 % strain; see {a.logs}/stiff.log")
    strain = lambda solver, dt=None: next(  # noqa: E731
        j["mean_strain"] for j in inter
        if j.get("solver") == solver and (dt is None or abs(j.get("dt", 0) - dt) < 1e-6))
    rk4 = [j for j in js if j.get("solver") == "rk4" and j.get("finite") is True]
    return {"iters": it, "big": float(big), "reps": int(med[0]), "bullet": float(med[1]), "i60": float(med[2]),
            "ibig": float(med[3]), "s_b": strain("bullet"), "s_60": strain("implicit-euler", 1 / 60),
            "s_big": strain("implicit-euler", float(big)), "rk4": rk4[-1] if rk4 else None}


def step_callgrind(a):
    if not a.replay and not shutil.which("valgrind"):
        raise FileNotFoundError("valgrind")
    out = {}
    for n in (8, 16) if a.quick else (100, 256):
        tot = {}
        for k in (1, 5):  # 2 and 6 steps: the first builds the plan, so the difference is 4 steady steps
            f = os.path.join(a.logs, f"callgrind.{n}.{k}")
            if not a.replay:
                run(a, f"callgrind-{n}-{k}", ["valgrind", "--tool=callgrind", f"--callgrind-out-file={f}",
                                           "--collect-atstart=no", "--toggle-collect=psys_solver_step",
                                           f"{a.build}/psys", "bench", f"cloth-{n}", "--steps", str(k), "--reps",
                                           "1", "--bandwidth", "1"], env={"OMP_NUM_THREADS": "1"})
            tot[k] = num(r"totals: (\d+)", read(f), int)
        out[n] = (tot[5] - tot[1]) / (4 * n * n)
    return out


def f2(x):
    return f"{x:.2f}"


def markdown(r, missing, when, com, hw, replay=None, quick=False):
    o = ["**--quick: tiny sizes, one round; these figures mean nothing.**", ""] if quick else []
    hw = re.sub(r"\((R|TM)\)", "", hw)
    again = f"; printed again by `--replay` from its outputs in `{replay}`" if replay else ""
    o.append(f"The latest figures, all from one run of the commands `python3 bench/results.py` runs ({when}, commit "
             f"{com}{again}) on a {hw}"
             + (f", STREAM triad {r['cloth']['triad']:.2f} GB/s on one thread" if "cloth" in r else "")
             + ". Each peer ran interleaved with psys in the same run, so the ratios hold within that run; absolute "
               "times drift with the host. Times are per particle-step (per atom-step for the pair forces), one "
               "thread unless stated. The floor is the bytes that must move per particle-step over the triad "
               "bandwidth ([below](#the-mass-spring-suite-psys-bench)); cases in cache run below it.")
    if missing:
        o.append("")
        o.append("Left out: " + "; ".join(f"{k} ({v})" for k, v in missing.items()) + ".")
    if "cloth" in r:
        c = r["cloth"]
        o += ["", f"**Mass-spring cloth against a plain C implementation** (`bench/cloth_vs_ref.sh`: medians of "
                  f"{r['rounds']} rounds; the reference is the peer `ref_cloth.c`, gcc -O3 -march=native, the "
                  "same sheet, springs and rk4):", "",
              "| case | psys | reference | psys / reference | floor | psys / floor | issue 8 target |",
              "| --- | --- | --- | --- | --- | --- | --- |"]
        target = {100: lambda p, fl: "≤ 50 ns: " + ("met" if p <= 50 else "**not met**"),
                  1024: lambda p, fl: "≤ 1.5 × floor: " + ("met" if p <= 1.5 * fl else "**not met**")}
        for n, (p, ref, ratio, fl, pf) in sorted(c["sizes"].items()):
            t = target[n](p, fl) if n in target else "—"
            o.append(f"| cloth-{n} rk4 | {f2(p)} ns | {f2(ref)} ns | {ratio:.3f} | {f2(fl)} ns | {pf:.2f} | {t} |")
        n2, p2, sp = c["two"]
        t2 = (f"≥ 1.6 × one thread: **{sp:.2f} ×**, " + ("met" if sp >= 1.6 else "not met")) if n2 == 1024 \
            else f"{sp:.2f} × one thread"
        o.append(f"| cloth-{n2} rk4, 2 threads | {f2(p2)} ns | — | — | — | — | {t2} |")
    if "suite" in r:
        s = r["suite"]
        o += ["", "**The whole suite** (`build/psys bench`, the default cases, medians of 5 repetitions):", "",
              "| case | rk4 | verlet | ns per spring evaluation (rk4, verlet) | rk4 / floor |",
              "| --- | --- | --- | --- | --- |"]
        for case in dict.fromkeys(case for case, _integrator in s):  # in the suite's order
            rk, vv = s.get((case, "rk4")), s.get((case, "verlet"))
            cell = lambda j: f"{j['ns_per_particle_step']:,.2f} ns" if j else "—"  # noqa: E731
            se = [f"{j['ns_per_spring_eval']:.2f}" for j in (rk, vv) if j and j.get("ns_per_spring_eval")]
            fl = f"{rk['times_floor']:.2f}" if rk else "arithmetic bound"
            o.append(f"| {case} | {cell(rk)} | {cell(vv)} | {', '.join(se) or '—'} | {fl} |")
    if "ceiling" in r:
        g = r["ceiling"]
        o += ["", "**What the 50 ns target asks of this host** (`build/spring_ceiling`, not psys, "
                  "[below](#ceiling-an-idealised-cloth-loop-on-this-host)): the square roots and divisions of "
                  f"cloth-100 rk4 alone take {g['divider']['floor_ns_per_particle_step']:.2f} ns per particle-step; "
                  "an idealised cloth loop written for the benchmark alone (no edge rows, pinned corners, per-run "
                  "parameters or same-bits guarantee) takes "
                  f"{g['ideal-cloth-fused']['ns_per_particle_step']:.2f} ns with the stage sums fused into it, "
                  f"{g['ideal-cloth-fused-partner']['ns_per_particle_step']:.2f} in the partner order, and "
                  f"{g['ideal-cloth-fused-psys-like']['ns_per_particle_step']:.2f} with psys's work in it. The "
                  "sections from \"What cloth-100 needs\" on give what was measured and tried."]
    if any(k in r for k in ("lj", "grid", "bh")):
        o += ["", "**Pair forces and N-body:**", "", "| case (command) | psys | peer | ratio |",
              "| --- | --- | --- | --- |"]
        if "lj" in r:
            j = r["lj"]
            o.append(f"| LJ melt, {j['atoms']:,} atoms, 100 verlet steps (`bench/lj_vs_lammps.sh`, medians of "
                     f"{r['rounds']}) | {j['psys']:.1f} ns | LAMMPS: {j['lammps']:.1f} ns (lists rebuilt every 20 "
                     f"steps unchecked), {j['check']:.1f} ns (`check yes`, rebuilt when needed, as psys does) | "
                     f"**{j['r']:.3f}**, **{j['rc']:.3f}** |")
        if "grid" in r:
            g = r["grid"]
            o.append(f"| the same liquid at {g['sizes']} sizes, 864 to 1,000,188 atoms (`build/pair_bench grid-scaling`) | "
                     f"{g['min_ns_per_atom_step']:.1f} ns ({g['n_at_min']:,} atoms) to "
                     f"{g['max_ns_per_atom_step']:.1f} ns ({g['n_at_max']:,}) | — | largest / smallest "
                     f"{g['max_over_min']:.2f} |")
        if "bh" in r:
            b, L = r["bh"]["summary"], r["bh"]["largest"]
            lo, hi = r["bh"]["err"]
            if b["crossover_n"] is not None:
                cross = (f"faster from {b['crossover_n']:,} bodies (interpolated; first faster size "
                         f"{b['first_faster_n']:,})")
            elif b.get("crossover_below") is not None:
                cross = f"faster at every size, from {b['crossover_below']:,} bodies"
            else:
                cross = f"not faster at the largest size, {b['crossover_above']:,} bodies"
            o.append(f"| Barnes–Hut θ {b['theta']:.1f} against direct sums, Plummer sphere (`build/pair_bench "
                     f"bh-crossover`) | {cross}, {L['ratio']:.2f} × faster at {L['n']:,}; force error "
                     f"{100 * lo:.2f}–{100 * hi:.2f} % | — | — |")
    if "stiff" in r:
        s = r["stiff"]
        o += ["", "**Stiff cloth against Bullet** (`bench/stiff_cloth.sh`, "
                  "[below](#stiff-cloth-implicit-euler-against-bullet): 100×100 cloth hanging from two corners, 1 s "
                  f"simulated; wall seconds per simulated second, medians of {s['reps']} interleaved runs; Bullet "
                  f"float64 at {s['iters']} position iterations, the fewest reaching ≤ 2 % mean strain):", "",
              "| code | setting | s per simulated s | mean strain | / Bullet |", "| --- | --- | --- | --- | --- |",
              f"| Bullet | {s['iters']} iterations, dt = 1/240 | {s['bullet']:.3f} | {100 * s['s_b']:.2f} % | 1 |",
              f"| psys implicit-euler | dt = 1/60 | {s['i60']:.3f} | {100 * s['s_60']:.2f} % | "
              f"**{s['i60'] / s['bullet']:.3f}** |",
              f"| psys implicit-euler | dt = {s['big']:g} (the largest of the sweep with ≤ 2 %) | {s['ibig']:.3f} | "
              f"{100 * s['s_big']:.2f} % | **{s['ibig'] / s['bullet']:.3f}** |"]
        if s["rk4"]:
            k = s["rk4"]
            o.append(f"| psys rk4 | dt = {k['dt']:g} (the largest stable of the sweep; one run, not interleaved) | "
                     f"{k['wall_s']:.2f} | {100 * k['mean_strain']:.2f} % | {k['wall_s'] / s['bullet']:.2f} |")
    if "callgrind" in r:
        c = r["callgrind"]
        o += ["", "**Callgrind** (instructions per particle-step, repeatable: "
                  "[below](#callgrind-instructions-per-particle-step-repeatable)): "
                  + " and ".join(f"**{v:.0f} Ir** for cloth-{n}" for n, v in sorted(c.items())) + " rk4."]
    o += ["", "MPI scaling: [docs/mpi.md](../docs/mpi.md#measured-scaling-on-this-machine)."]
    return "\n".join(o)


def main():
    ap = argparse.ArgumentParser(description="Runs the benchmarks of bench/README.md's Results; prints them.")
    ap.add_argument("build", nargs="?", default="build")
    ap.add_argument("--logs", help="folder for the raw outputs (default: a new one under /tmp)")
    ap.add_argument("--skip", default="", help="comma-separated steps to leave out: " + ",".join(STEPS))
    ap.add_argument("--rounds", type=int, default=3, help="interleaved rounds of cloth and lj (default 3)")
    ap.add_argument("--quick", action="store_true",
                    help="every step at tiny sizes and one round: checks that it all runs and parses (figures "
                         "meaningless)")
    ap.add_argument("--replay", action="store_true",
                    help="print the section again from the raw outputs already in --logs, running nothing")
    ap.add_argument("--check", metavar="FILE",
                    help="exit 1 unless FILE holds the printed section word for word (with --replay: the docs' "
                         "figures are those of the outputs kept)")
    a = ap.parse_args()
    if a.replay and not a.logs:
        ap.error("--replay needs --logs DIR")
    if a.replay and a.quick:
        ap.error("--quick runs the programs; --replay runs none")
    if a.quick:
        a.rounds = 1
    skip = {s for s in a.skip.split(",") if s}
    bad = skip - set(STEPS)
    if bad:
        ap.error(f"unknown step(s) {', '.join(sorted(bad))}; steps: {', '.join(STEPS)}")
    if not a.replay and not os.path.exists(os.path.join(ROOT, a.build, "psys")):
        ap.error(f"{a.build}/psys not found: build first (make build)")
    a.logs = a.logs or tempfile.mkdtemp(prefix="psys-results-")
    meta = os.path.join(a.logs, "meta.json")  # what the run was of, for --replay
    if a.replay:
        if not os.path.exists(meta):
            ap.error(f"{meta} not found: --logs names no folder of a results.py run")
        m = json.loads(read(meta))
    else:
        os.makedirs(a.logs, exist_ok=True)
        m = {"date": datetime.date.today().isoformat(), "commit": commit(), "host": host()}
        with open(meta, "w", encoding="utf-8") as f:
            json.dump(m, f)
    when, com, hw = m["date"], m["commit"], m["host"]
    r, missing, failed = {"rounds": a.rounds}, {}, {}
    for name in STEPS:
        if name in skip:
            continue
        try:
            r[name] = globals()[f"step_{name}"](a)
        except FileNotFoundError as e:
            missing[name] = f"needs {e.args[0] if e.args else e}"
            log(f"{name}: left out ({missing[name]})")
        except (RuntimeError, OSError, KeyError, ValueError, StopIteration) as e:  # a format it does not know
            failed[name] = f"failed: {e}"
            log(f"{name}: {failed[name]}")
    replayed = None
    if a.replay:  # named as in the source tree, so the text is the same from any folder
        rel = os.path.relpath(os.path.abspath(a.logs), ROOT)
        replayed = a.logs if rel.startswith("..") else rel
    text = markdown(r, {**missing, **failed}, when, com, hw, replayed, a.quick)
    print(text)
    log(f"raw outputs in {a.logs}")
    if a.check and text not in read(a.check):
        log(f"{a.check} does not hold this section as printed above")
        return 1
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
