"""A weak-scaling model of a run past one machine (issue 44): what a 100M-tet P1 and a 30M-tet P2 run on 1,000 ranks
would spend where, from per-rank costs measured here, and what it would hit first.

    python scripts/weak_model.py OUT [--quick] [--ranks 1,16,128,1000] [--alpha-us 2.0] [--rank0-meta-ms 0.27]

Measured (one rank of this machine, `bend`, one step of a Kuhn box refined once with -refine, CG + GAMG, -log_view):
per tet (or node) the Setup stage (DM, space, kernels, pattern, the first frame's start), the refinement, the
Jacobian's assembly, GAMG's set-up, a Krylov iteration, an output frame's per-rank part and fields; and rank 0's
serial read of a coarse .msh per tet. Extrapolated with these terms, each stated:
  - a rank's own work is the measured per-tet cost times its tets (weak scaling keeps that constant);
  - every Krylov iteration adds 3 global reductions (CG: two dots and a norm) of alpha * log2(P) each
    (--alpha-us: a small-message allreduce stage on a cluster interconnect; 2 us is an InfiniBand-class figure);
  - GAMG's iterations grow with the mesh as measured over four refinements of the bar (BENCHMARKS.md, "Solver
    scalability": 5.8 -> 7.2 CG iterations a Newton step from 59k to 521k tets: +0.45 per doubling of the tets);
  - GAMG's set-up makes the global reductions it made here (-log_view counts them; a reduction is counted on one
    rank too), each of alpha * log2(P), and a third more for each 8x of the global problem (a coarse level more,
    taking the measured hierarchy as three levels);
  - rank 0's serial work: the coarse mesh read (-refine K: the fine mesh's tets / 8^K; none for a prepared coarse
    mesh) and, per output frame, the main file's metadata, one virtual-dataset mapping per rank per field
    (--rank0-meta-ms per rank: HE_OutRank0 grew 2.0 -> 6.0 ms from 4 to 16 ranks on the 16-core machine, BENCHMARKS.md
    "The output's layouts"; about 0.27 ms a rank);
  - the 32-bit index range: 3 dofs a node below 2^31; DMPlex points (cells, faces, edges, vertices) below 2^31.
Per-tet costs are slopes between two sizes (-refine 1 and 2 of one coarse box: P1 120k -> 960k tets,
P2 6k -> 49k; --quick: P1 16k -> 125k, P2 2k -> 17k), so fixed costs are not counted per tet."""
import argparse
import math
import os
import sys

import h5py
import numpy as np

sys.path.append(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))     # (after an installed hyperelastic)

from scripts.bench_output import stages  # noqa: E402
from scripts.bench_output_ranks import kuhn_box  # noqa: E402
from scripts.bench_prepared import run  # noqa: E402
from scripts.bench_refine import NOTE  # noqa: E402

import launch  # noqa: E402
EVENTS = ("SNESJacobianEval", "PCSetUp", "KSPSolve", "HE_OutRankPart", "HE_OutFields", "HE_OutRank0")


def events(log):
    """{event: (max seconds over ranks, global reductions)} of -log_view's event table, summed over the stages (the
    table lists an event once per stage it ran in)."""
    out = {}
    with open(log) as fh:
        for line in fh:
            f = line.split()
            if f and f[0] in EVENTS and len(f) > 10:
                t, r = out.get(f[0], (0.0, 0.0))
                out[f[0]] = (t + float(f[3]), r + float(f[9]))
    return out


def run_once(out, coarse, order, refine):
    """One rank's costs of `bend` on the coarse mesh refined `refine` times (one step): {tets, nodes, seconds per
    part, Krylov iterations and reductions per Newton step, peak memory}."""
    res, log = os.path.join(out, f"m{order}_{refine}.h5"), os.path.join(out, f"m{order}_{refine}.log")
    _, err = run(launch.command(["run", "bend", "-mesh", coarse, "-refine", refine, "-order", order, "-dt", "0.01",
                                 "-final_time", "0.01", "-ksp_type", "cg", "-pc_type", "gamg", "-output", res,
                                 "-log_view", f":{log}"]))
    m = NOTE.search(err)
    with h5py.File(res) as f:
        tets, nodes = f["mesh/tetra"].shape[0], f["mesh/points"].shape[0]
        its, newton = int(f["stats/ksp_its"][:].sum()), int(f["stats/newton_its"][:].sum())
        frames, mem = f["x"].shape[0], float(np.max(f.attrs["peak_rss_mb_per_rank"]))
    st, ev = stages(log), events(log)
    refine_s, read0 = float(m.group(1)), float(m.group(3) or 0)
    return {"tets": tets, "nodes": nodes, "refine": refine_s, "read0": read0, "coarse": tets // 8 ** refine,
            "setup": st["Setup"] - refine_s - read0, "jac": ev["SNESJacobianEval"][0] / newton,
            "pcsetup": ev["PCSetUp"][0] / newton, "pcsetup_reductions": ev["PCSetUp"][1] / newton,
            "krylov_it": ev["KSPSolve"][0] / max(its, 1), "its": its / newton,
            "out": sum(ev.get(k, (0, 0))[0] for k in ("HE_OutRankPart", "HE_OutFields")) / frames, "mem": mem}


PER_TET = ("refine", "setup", "jac", "pcsetup", "krylov_it", "out", "mem")


def measure(out, box, order):
    """Per-tet costs of one rank: the slope between -refine 1 and -refine 2 of one coarse Kuhn box (8x the tets), so
    a process's fixed costs (imports, PETSc's start, the first frame's file) do not count as per-tet ones; the
    finer run's iterations and reductions; rank 0's coarse read per coarse tet."""
    nx, ny, nz = box
    coarse = os.path.join(out, f"coarse_{nx}x{ny}x{nz}.msh")
    kuhn_box(nx, ny, nz, coarse)
    a, b = run_once(out, coarse, order, 1), run_once(out, coarse, order, 2)
    m = dict(b)
    for k in PER_TET:
        m[k] = (b[k] - a[k]) / (b["tets"] - a["tets"])          # per tet
    m["fixed_mem"] = a["mem"] - m["mem"] * a["tets"]
    m["read0"] = b["read0"] / b["coarse"]
    return m


def model(m, tets, P, refine, a):
    """Seconds per part of a run of `tets` tetrahedra on P ranks (per rank tets / P), one Newton step, one frame."""
    scale = tets / P
    lat = a.alpha_us * 1e-6 * max(math.log2(P), 1)
    its = m["its"] + 0.45 * math.log2(max(tets / m["tets"], 1))
    levels = max(math.log(max(tets / m["tets"], 1), 8), 0)
    return {
        "rank 0: coarse read (.msh; prepared: 0)": m["read0"] * tets / 8 ** refine,
        "refine": m["refine"] * scale,
        "set-up (DM, space, kernels, pattern)": m["setup"] * scale,
        "Jacobian / Newton": m["jac"] * scale,
        "GAMG set-up / Newton": m["pcsetup"] * scale + m["pcsetup_reductions"] * (1 + levels / 3) * lat,
        "Krylov / Newton": its * (m["krylov_it"] * scale + 3 * lat),
        "output / frame (own rows)": m["out"] * scale,
        "rank 0: output metadata / frame": a.rank0_meta_ms * 1e-3 * P,
    }, its


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out")
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--ranks", default="1,16,128,1000")
    ap.add_argument("--alpha-us", type=float, default=2.0)
    ap.add_argument("--rank0-meta-ms", type=float, default=0.27)
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    cases = [("P1", 1, (13, 5, 5) if a.quick else (25, 10, 10), 100e6, 3),
             ("P2", 2, (5, 3, 3) if a.quick else (8, 4, 4), 30e6, 2)]
    for name, order, box, tets, refine in cases:
        m = measure(a.out, box, order)
        nodes_per_tet = m["nodes"] / m["tets"]
        print(f"\n## {name}: {tets / 1e6:.0f}M tets (-refine {refine} of a {tets / 8 ** refine / 1e3:.0f}k-tet coarse "
              f".msh)")
        print(f"measured on 1 rank, slopes from {m['tets'] // 8} to {m['tets']} tets ({m['nodes']} nodes): set-up "
              f"{m['setup'] * 1e6:.1f} us/tet, refine {m['refine'] * 1e6:.2f} us/tet, Jacobian {m['jac'] * 1e6:.2f} "
              f"us/tet, GAMG set-up {m['pcsetup'] * 1e6:.2f} us/tet, Krylov {m['krylov_it'] * 1e9:.0f} ns/tet an "
              f"iteration ({m['its']:.1f} a Newton step), output {m['out'] * 1e6:.2f} us/tet a frame, rank 0's coarse "
              f"read {m['read0'] * 1e6:.1f} us/tet, memory {m['mem'] * 1e3:.2f} kB/tet + {m['fixed_mem']:.0f} MB")
        dofs = 3 * nodes_per_tet * tets
        print(f"dofs {dofs / 1e6:.0f}M ({dofs / 2 ** 31:.2f} of the 32-bit range); "
              f"peak memory a rank at 1000 ranks ~ {m['fixed_mem'] + m['mem'] * tets / 1000:.0f} MB")
        ranks = [int(r) for r in a.ranks.split(",")]
        rows = [model(m, tets, P, refine, a) for P in ranks]
        print("| part | " + " | ".join(f"{P} ranks" for P in ranks) + " |")
        print("|---|" + "---|" * len(ranks))
        for key in rows[0][0]:
            print(f"| {key} | " + " | ".join(f"{r[0][key]:.3g}" for r in rows) + " |")
        print("| Krylov iterations / Newton | " + " | ".join(f"{r[1]:.1f}" for r in rows) + " |")
        last = rows[-1][0]
        serial = last["rank 0: coarse read (.msh; prepared: 0)"] + last["rank 0: output metadata / frame"]
        print(f"at {ranks[-1]} ranks: rank 0's serial parts {serial:.2f} s against a Newton step's "
              f"{last['Jacobian / Newton'] + last['GAMG set-up / Newton'] + last['Krylov / Newton']:.2f} s")


if __name__ == "__main__":
    main()
