"""Forces on the body at the end of a run (issue 34): the reaction of every constrained surface and the
resultant of every load, with their moments about the origin.

The residual r(x) of the effects (system.residual_local, without the constrained rows' replacement) is,
at a node, the force the node needs from outside: r = M a + C v + f_int - f_ext. At a free node it is zero
when the solve has converged; at a held node it is the support's force on the body. So a constrained
surface's reaction is the sum of r over its nodes' components that surface holds, and an effect's force on the body
is minus the sum of its own residual over every node (loads: the applied force; inertia: the d'Alembert force
-M a; damping: -C v). The internal forces sum to zero, so reactions + loads + inertia + damping = 0 to the
solver's tolerance. Sums run over each rank's local nodes, ghosts included: every cell lives on one rank,
so each cell's contribution is counted once.

Which row a held component's reaction belongs to (issue 70): the surfaces that hold that component of that node (a
surface held in y only, `-fix front:y`, never shows the z reaction of the nodes it shares with `-fix zsym:z`); where
several surfaces hold the same component of a shared node (`-fix left,bottom`: their common edge), it is split equally
among them. So the rows of every component add up to the total of the held components, which the row `reaction
all_held` gives (where more than one surface is held) and the balance line sums with the loads. The table names the
components each row holds.
"""
import numpy as np
from mpi4py import MPI


TOTAL = "all_held"         # the row of every held component once (surfaces sharing held nodes count them in both rows;
                           # a name without spaces or parentheses: it is also a statistics column's, reaction_all_held_Fz)
TOTALS = (TOTAL, "(all held)")   # (its name in outputs written before 2026-11-26, which report still reads)


def surface_forces(scene, system, x):
    """[(kind, name, F (3,), M (3,))]: ('reaction', set) for each constrained surface (the components it holds; a
    component several surfaces hold at a node split equally among them), ('load', effect) for each other effect's
    force on the body; x: the local positions. Collective."""
    sp = system.space
    mpi = sp.mpi
    each = [(e, system.residual_local(x, effects=[e]).reshape(-1, 3)) for e in system.effects]   # once each
    r = sum(re for _, re in each)                       # the residual of all effects
    held = system.cmask.reshape(-1, 3)
    X = x.reshape(-1, 3)
    rows = []
    holds = held_components(scene)
    masks = []
    for name, comps in holds.items():                   # the components each surface holds, at its vertices
        m = np.zeros(held.shape, bool)
        m[np.ix_(sp.set_vertices(name), ["xyz".index(c) for c in comps])] = True
        masks.append(m & held)
    count = sum(m.astype(np.int64) for m in masks) if masks else np.zeros(held.shape, np.int64)
    share = np.where(count > 0, r / np.maximum(count, 1), 0.0)
    for name, m in zip(holds, masks):
        f = np.where(m, share, 0.0)
        rows.append(("reaction", name, f.sum(axis=0), np.cross(X, f).sum(axis=0)))
    if len(holds) > 1:                  # every held component once: what the loads balance
        f = np.where(held, r, 0.0)
        rows.append(("reaction", TOTAL, f.sum(axis=0), np.cross(X, f).sum(axis=0)))
    loads = {}                # (effects of one name add up: contact with analytic obstacles and with triangles)
    for e, re in each:
        if not e.internal:
            F, M = -re.sum(axis=0), -np.cross(X, re).sum(axis=0)
            if e.name in loads:
                F, M = loads[e.name][0] + F, loads[e.name][1] + M
            loads[e.name] = (F, M)
    rows += [("load", name, F, M) for name, (F, M) in loads.items()]
    local = np.array([np.concatenate([F, M]) for _, _, F, M in rows]).reshape(-1, 6)
    total = np.empty_like(local)
    mpi.Allreduce(local, total, op=MPI.SUM)
    return [(k, n, t[:3], t[3:]) for (k, n, _, _), t in zip(rows, total)]


def constrained_sets(scene):
    """The surfaces the scene holds (-fix, -prescribe_faces, -rigid), in order, each once."""
    return list(held_components(scene))


def held_components(scene):
    """{surface: the components the scene holds on it ("xyz", "y", ...)} of -fix, -prescribe_faces (their S:xyz) and
    -rigid (all three), in order; a surface named by several options holds the union."""
    out = {}
    for effect in ("fixed", "prescribed", "rigid"):
        if effect not in scene.effects:
            continue
        params = scene.effects[effect]
        faces = params.faces if effect != "rigid" else ((params.surface, "xyz"),)
        for name, comps in faces:
            held = set(out.get(name, "")) | set(comps)
            out[name] = "".join(c for c in "xyz" if c in held)
    return out


def table(rows, t, holds=None):
    """The end-of-run lines: one per surface (with the components it holds, where `holds` {surface: "xyz"} says) and
    load, and their sum against the largest force."""
    holds = holds or {}
    lines = [f"forces at t = {t:.12g} (N; moments about the origin, N m):"]
    for kind, name, F, M in rows:
        which = f" (holds {holds[name]})" if kind == "reaction" and name in holds else ""
        lines.append(f"  {kind} {name}{which}: F = ({F[0]:.6g}, {F[1]:.6g}, {F[2]:.6g}), "
                     f"M = ({M[0]:.6g}, {M[1]:.6g}, {M[2]:.6g})")
    if rows:
        total = any(k == "reaction" and n in TOTALS for k, n, _, _ in rows)
        part = [(k, F) for k, n, F, _ in rows if not (total and k == "reaction" and n not in TOTALS)]
        S = sum(F for _, F in part)
        big = max(np.linalg.norm(F) for _, _, F, _ in rows)       # (a surface's own reaction, where no load)
        rel = np.linalg.norm(S) / big if big > 0 else 0.0
        lines.append(f"  sum: F = ({S[0]:.3g}, {S[1]:.3g}, {S[2]:.3g}) ({rel:.2g} of the largest force)")
    return lines


def record(rows, holds=None):
    """The rows as the output file's `forces` attribute records them (JSON-able; a reaction's `holds`: its
    components)."""
    holds = holds or {}
    return [{"kind": k, "name": n, "F": [float(v) for v in F], "M": [float(v) for v in M]}
            | ({"holds": holds[n]} if k == "reaction" and n in holds else {}) for k, n, F, M in rows]
