"""The statistics a run writes: FILE.h5:stats/<column>, one entry per step attempt (rejected attempts
included). Declared here once: the integrator writes these columns (output.Writer refuses others),
and the studies, the hard-case matrix, the reproduction scripts and the tests read them from here. The
energies are the effects' own (effects.energies(): each effect declares the columns it reports and their
part in energy_total).
"""
import re

import numpy as np
from mpi4py import MPI

from ..physics.effects import energies
from .rigid import COLUMNS as RIGID_COLUMNS

# column: (type, meaning)
COLUMNS = {
    "step": (int, "number of the step this attempt tries to complete (accepted steps before it + 1)"),
    "time": (float, "time at the end of the attempt [s]"),
    "dt": (float, "size of the attempt [s] (step control halves it after a rejection)"),
    "snes_reason": (int, "SNES converged reason (negative: diverged)"),
    "newton_its": (int, "Newton iterations"),
    "ksp_its": (int, "Krylov iterations, summed over the Newton iterations"),
    "residual_evals": (int, "residual evaluations (MFFD's included)"),
    "residual_seconds": (float, "wall time in residual evaluations [s]"),
    "objective_evals": (int, "evaluations of the incremental potential (the energy line search's merit)"),
    "objective_seconds": (float, "wall time in objective evaluations [s]"),
    "inversion_cuts": (int, "Newton updates the inversion guard shortened"),
    "contact_cuts": (int, "Newton updates shortened so that no contact node reaches an obstacle (-obstacle)"),
    "rejected": (int, "1: step control refused the attempt (the state did not move); 0: accepted"),
    "wall_s": (float, "wall time of the attempt [s]"),
    "energy_total": (float, "the sum of the energies below with their signs (kinetic + elastic + potentials "
                            "- work of the loads) after the step [J]"),
    "energy_dissipated": (float, "total energy at t = 0 minus energy_total [J]: physical damping plus the "
                                 "integrator's numerical dissipation (and the work of prescribed motions)"),
    "error_estimate": (float, "-integrator ts with an adaptor: the step's weighted local error estimate "
                              "(TSEvaluateWLTE, accepted when <= 1)"),
    "dt_next": (float, "-integrator ts: the step size chosen for the next step [s]"),
}
COLUMNS.update({e.column: (float, e.meaning) for e in energies().values()})
COLUMNS.update(RIGID_COLUMNS)      # a run with a rigid face (-rigid)
ENERGY_TERMS = tuple((e.column, e.sign, e.work) for e in energies().values() if e.sign)   # energy_total's parts
# effect_<name>_<kind>, for every effect the run built
EFFECT_COLUMNS = {
    "evals": (int, "residual evaluations of the effect"),
    "applies": (int, "tangent applications, diagonals and assemblies of the effect"),
    "seconds": (float, "wall time in the effect [s]"),
}


# <kind>_<name>_<component>: the forces on the body after each accepted step (forces.py: 'reaction' of each held
# surface, 'load' of each other effect), NaN in rejected attempts' rows
FORCE_KINDS = ("reaction", "load")
FORCE_COMPONENTS = ("Fx", "Fy", "Fz", "Mx", "My", "Mz")


def force_columns(rows):
    """{column: value} of forces.surface_forces' rows."""
    out = {}
    for kind, name, F, M in rows:
        for c, v in zip(FORCE_COMPONENTS, list(F) + list(M)):
            out[f"{kind}_{name}_{c}"] = float(v)
    return out


# <name>_<quantity>: each obstacle's results (seams.Results.result_rows) after each accepted step: its force on the
# body, its contact area and its translation, NaN in rejected attempts' rows; `self` (self-contact: the surface's pairs
# with itself) the same, its force the sum of balanced pairs, and the force they carry
RESULT_QUANTITIES = {"Fx": "force on the body [N], x", "Fy": "force on the body [N], y", "Fz": "force on the body "
                     "[N], z", "area": "reference area of the contact nodes within dhat [m^2]",
                     "ux": "translation [m], x", "uy": "translation [m], y", "uz": "translation [m], z",
                     "carried": "force carried by the pairs (self-contact: half the sum of its nodal forces' "
                                "magnitudes) [N]"}
RESULT_NAMES = re.compile(r"(obstacle\d+|self)_")       # the rows' names: obstacle1, obstacle2, ..., self


def result_columns(rows):
    """{column: value} of the Results rows (seams.ResultRow), summed over the ranks already."""
    out = {}
    for name, F, area, u, carried in rows:
        out.update({f"{name}_F{c}": float(v) for c, v in zip("xyz", F)})
        out[f"{name}_area"] = float(area)
        out.update({f"{name}_u{c}": float(v) for c, v in zip("xyz", u)})
        if carried is not None:
            out[f"{name}_carried"] = float(carried)
    return out


def forces_of(st, i):
    """[(kind, name, F (3,), M (3,))] of statistics row i (the columns force_columns made), in column order."""
    rows = {}
    for col in st:
        kind, _, rest = col.partition("_")
        name, _, comp = rest.rpartition("_")
        if kind in FORCE_KINDS and comp in FORCE_COMPONENTS and name:
            rows.setdefault((kind, name), np.zeros(6))[FORCE_COMPONENTS.index(comp)] = st[col][i]
    return [(k, n, v[:3], v[3:]) for (k, n), v in rows.items()]


def effect_column(effect, kind):
    return f"effect_{effect}_{kind}"


def column_type(name):
    """int or float for a declared column; KeyError for any other name."""
    if name in COLUMNS:
        return COLUMNS[name][0]
    if name.startswith("effect_"):
        kind = name.rsplit("_", 1)[-1]
        if kind in EFFECT_COLUMNS:
            return EFFECT_COLUMNS[kind][0]
    if name.partition("_")[0] in FORCE_KINDS and name.rpartition("_")[2] in FORCE_COMPONENTS:
        return float
    if RESULT_NAMES.match(name) and name.rpartition("_")[2] in RESULT_QUANTITIES:
        return float
    raise KeyError(f"'{name}' is not a declared statistics column (hyperelastic/stats.py)")


def read(f):
    """{column: array} of an open output file (h5py.File)."""
    return {k: f["stats"][k][:] for k in f["stats"]}


# a time a user gives (report --watch Q@T, --forces) matches the nearest frame or step time within this relative
# distance: half a unit of the 6th significant digit that the progress lines and messages print (0.333333 for 1/3)
TIME_DIGITS = 5e-6


def at_time(times, t):
    """Indices of `times` at t: those equal (to 1e-12) to the time nearest t, where that is within 1e-9 of max(1, |t|)
    or within TIME_DIGITS of |t| (a time as printed); none otherwise."""
    times = np.asarray(times, float)
    if not len(times):
        return np.zeros(0, np.int64)
    near = times[np.argmin(np.abs(times - t))]
    if abs(near - t) > max(1e-9 * max(1.0, abs(t)), TIME_DIGITS * abs(t)):
        return np.zeros(0, np.int64)
    return np.flatnonzero(np.abs(times - near) <= 1e-12 * max(1.0, abs(near)))


def accepted_at(st, t):
    """Indices of the accepted attempts that end at time t (none in a file without statistics)."""
    acc = np.flatnonzero(accepted(st))
    return acc[at_time(st["time"][acc], t)] if len(acc) else acc


def accepted(st):
    """Boolean mask of the accepted attempts."""
    n = len(st.get("step", []))
    return ~st.get("rejected", np.zeros(n, np.int64)).astype(bool)


def extremal(column):
    """Whether a statistics column is a smallest or largest value (J_min, contact_dmin: combined by min or max), which
    may be infinite (no contact pair within reach), rather than an energy."""
    e = energies().get(column)
    return e is not None and e.combine != "sum"


def energy_sum(values, with_work=True):
    """energy_total from {column: value (a number or an array)}: the effects' energies with their signs
    (kinetic + elastic + potentials - work of the loads); with_work=False: the body's energy alone."""
    tot = 0.0
    for col, sign, work in ENERGY_TERMS:
        if col in values and (with_work or not work):
            tot = tot + values[col] if sign > 0 else tot - values[col]
    return tot


def total_energy(st, with_work=True):
    """energy_total of the accepted attempts of a run's statistics (read())."""
    acc = accepted(st)
    return energy_sum({k: st[k][acc] for k, _, _ in ENERGY_TERMS if k in st}, with_work)


COMBINE = {"sum": sum, "min": min, "max": max}
REDUCE = {"min": MPI.MIN, "max": MPI.MAX}


def effect_energies(effects, mpi, x, v):
    """{column: value} of the effects' energies at local positions x and velocities v, over the ranks (energies():
    how instances and ranks combine). Collective."""
    how = energies()
    out = {}
    for e in effects:
        for k, val in e.energy(x, v).items():     # several instances (e.g. loads): combined
            out[k] = val if k not in out else COMBINE[how[k].combine]((out[k], val))
    res = {k: mpi.allreduce(out.pop(k), op=REDUCE[how[k].combine]) for k in list(out)
           if how[k].combine != "sum"}
    keys = sorted(out)                       # everything else is additive over ranks: one reduction
    sums = np.array([out[k] for k in keys], dtype=float)
    tot = np.empty_like(sums)
    mpi.Allreduce(sums, tot, op=MPI.SUM)
    res.update(zip(keys, tot.tolist()))
    return res


def effect_counters(effects):
    """{effect name: (residual evaluations, applications, seconds)}, several instances of an effect summed."""
    out = {}
    for e in effects:
        prev = out.get(e.name, (0, 0, 0.0))
        out[e.name] = (prev[0] + e.evals, prev[1] + e.applies, prev[2] + e.seconds)
    return out
