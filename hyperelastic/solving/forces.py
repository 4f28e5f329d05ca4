"""Forces on the body at the end of a run (issue 34): the reaction of every constrained surface and the
resultant of every load, with their moments about the origin.

The residual r(x) of the effects (system.residual_local, without the constrained rows' replacement) is,
at a node, the force the node needs from outside: r = M a + C v + f_int - f_ext. At a free node it is zero
when the solve has converged; at a held node it is the support's force on the body. So a constrained
surface's reaction is the sum of r over its nodes' held components, and an effect's force on the body is
minus the sum of its own residual over every node (loads: the applied force; inertia: the d'Alembert force
-M a; damping: -C v). The internal forces sum to zero, so reactions + loads + inertia + damping = 0 to the
solver's tolerance. Sums run over each rank's local nodes, ghosts included: every cell lives on one rank,
so each cell's contribution is counted once. A node on two constrained surfaces counts in both surfaces'
rows; with more than one such surface a row `reaction all_held` counts every held component once, and the
balance line sums that row and the loads.
"""
import numpy as np
from mpi4py import MPI

from ..physics.effects import SPECS

TOTAL = "all_held"         # the row of every held component once (surfaces sharing held nodes count them in both rows;
                           # a name without spaces or parentheses: it is also a statistics column's, reaction_all_held_Fz)
TOTALS = (TOTAL, "(all held)")   # (its name in outputs written before 2026-11-26, which report still reads)


def surface_forces(scene, system, x):
    """[(kind, name, F (3,), M (3,))]: ('reaction', set) for each constrained surface, ('load', effect) for
    each other effect's force on the body; x: the local positions. Collective."""
    sp = system.space
    mpi = sp.mpi
    each = [(e, system.residual_local(x, effects=[e]).reshape(-1, 3)) for e in system.effects]   # once each
    r = sum(re for _, re in each)                       # the residual of all effects
    held = system.cmask.reshape(-1, 3)
    X = x.reshape(-1, 3)
    rows = []
    names = constrained_sets(scene)
    for name in names:
        v = sp.set_vertices(name)
        f = np.where(held[v], r[v], 0.0)
        rows.append(("reaction", name, f.sum(axis=0), np.cross(X[v], f).sum(axis=0)))
    if len(names) > 1:                  # every held component once: what the loads balance
        f = np.where(held, r, 0.0)
        rows.append(("reaction", TOTAL, f.sum(axis=0), np.cross(X, f).sum(axis=0)))
    for e, re in each:
        if not e.internal:
            rows.append(("load", e.name, -re.sum(axis=0), -np.cross(X, re).sum(axis=0)))
    local = np.array([np.concatenate([F, M]) for _, _, F, M in rows]).reshape(-1, 6)
    total = np.empty_like(local)
    mpi.Allreduce(local, total, op=MPI.SUM)
    return [(k, n, t[:3], t[3:]) for (k, n, _, _), t in zip(rows, total)]


def constrained_sets(scene):
    """The surfaces the scene holds (-fix, -prescribe_faces, -rigid), in order, each once."""
    names = []
    for effect in ("fixed", "prescribed", "rigid"):
        uses = SPECS[effect].set_uses(scene.effects[effect]) if effect in scene.effects else []
        for _, name, _ in uses:
            if name not in names:
                names.append(name)
    return names


def table(rows, t):
    """The end-of-run lines: one per surface and load, and their sum against the largest force."""
    lines = [f"forces at t = {t:.6g} (N; moments about the origin, N m):"]
    for kind, name, F, M in rows:
        lines.append(f"  {kind} {name}: F = ({F[0]:.6g}, {F[1]:.6g}, {F[2]:.6g}), "
                     f"M = ({M[0]:.6g}, {M[1]:.6g}, {M[2]:.6g})")
    if rows:
        total = any(k == "reaction" and n in TOTALS for k, n, _, _ in rows)
        part = [(k, F) for k, n, F, _ in rows if not (total and k == "reaction" and n not in TOTALS)]
        S = sum(F for _, F in part)
        big = max(np.linalg.norm(F) for _, _, F, _ in rows)       # (a surface's own reaction, where no load)
        rel = np.linalg.norm(S) / big if big > 0 else 0.0
        lines.append(f"  sum: F = ({S[0]:.3g}, {S[1]:.3g}, {S[2]:.3g}) ({rel:.2g} of the largest force)")
    return lines


def record(rows):
    """The rows as the output file's `forces` attribute records them (JSON-able)."""
    return [{"kind": k, "name": n, "F": [float(v) for v in F], "M": [float(v) for v in M]} for k, n, F, M in rows]
