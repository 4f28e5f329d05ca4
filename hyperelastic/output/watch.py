"""Quantities a user watches, by name, in an output file: `study refinement --watch`, `study price --watch`
and `report --watch` read them here.

    QUANTITY[:WHERE][@WHEN]

QUANTITY[:WHERE] is one of
  max_displacement            the largest |u| over the vertices
  max_displacement:SURFACE    the largest |u| over a surface's nodes
  point:X,Y,Z                 |u| at a material point (reference coordinates), interpolated in its cell
  u_x:X,Y,Z (u_y, u_z)        a displacement component there
  von_mises:X,Y,Z             the von Mises stress of the cell holding the material point (the cell field)
  stress_xx:X,Y,Z (_yy, _zz, _xy, _xz, _yz)  a Cauchy stress component there (the cell field; -output_fields stress)
  pressure:X,Y,Z              the mixed formulation's pressure there (mean stress, positive in tension), interpolated
  max_von_mises               the largest cell von Mises stress; max_von_mises:SURFACE over the cells with a
                              facet on the surface
  elastic_energy, total_energy  the run's statistics (elastic; energy_total: kinetic + elastic + potentials
                              - work of the loads)
  reaction:SURFACE            |F| of a held surface's reaction (reaction_x:SURFACE, _y, _z: a component)
  moment:SURFACE[:X,Y,Z]      |M| of a held surface's reaction moment about the point X,Y,Z (default the origin;
                              moment_x, _y, _z: a component), e.g. the torque on a twisted face: M_p = M_0 - p x F
and WHEN is the last frame (default), @T (the frame at time T) or @max (the largest magnitude over the run's
frames; for the energies over its accepted steps). SURFACE is a physical surface of the mesh (looked up in
the run's .msh) or a geometric selector (x=V, box=..., normal=+z; sets.py). Reactions come from the run's
statistics (every accepted step records them) or, at the end, from its `forces` attribute.
"""
import json
import math
import os
import shlex
from dataclasses import dataclass

import h5py
import numpy as np

from ..solving import stats
from ..core.errors import UserError
from ..core.files import completed_frames
from ..mesh.read import interpolate, locate, read_mesh
from .fields import TENSOR6

HELP = ("max_displacement[:SURFACE], point:X,Y,Z (|u| there), u_x:X,Y,Z / u_y / u_z, von_mises:X,Y,Z, "
        "stress_xx:X,Y,Z / _yy / _zz / _xy / _xz / _yz, pressure:X,Y,Z, "
        "max_von_mises[:SURFACE], elastic_energy, total_energy, reaction:SURFACE / reaction_x / _y / _z, "
        "moment:SURFACE[:X,Y,Z] / moment_x / _y / _z (about X,Y,Z; default the origin); "
        "each may end in @T (at time T) or @max (its largest magnitude over the run)")
COMPONENTS = {"x": 0, "y": 1, "z": 2}
STRESS = {f"stress_{'xyz'[i]}{'xyz'[j]}": k for k, (i, j) in enumerate(TENSOR6)}      # the stress field's columns
AT_POINT = ("point", "u_x", "u_y", "u_z", "von_mises", "pressure") + tuple(STRESS)
ON_SURFACE = ("max_displacement", "max_von_mises")          # the SURFACE optional
REACTIONS = ("reaction", "reaction_x", "reaction_y", "reaction_z")
MOMENTS = ("moment", "moment_x", "moment_y", "moment_z")
ENERGIES = {"elastic_energy": "elastic", "total_energy": "energy_total"}


@dataclass(frozen=True)
class Watch:
    spec: str            # as the user wrote it
    kind: str            # QUANTITY
    where: object        # the material point (np.ndarray), the surface (str) or None
    when: object         # None (the last frame), a time (float) or "max"
    about: object = None  # a moment's point (np.ndarray; None: the origin)

    @property
    def kind_of_error(self):
        """'energy' (converges as the energy norm's square), 'reaction' (likewise) or 'displacement'."""
        return ("energy" if self.kind in ENERGIES else "reaction" if self.kind in REACTIONS + MOMENTS
                else "displacement")


def point3(text):
    """The point X,Y,Z of `text` (an array), or None when it is not three finite numbers."""
    try:
        p = [float(v) for v in text.split(",")]
    except ValueError:
        return None
    return np.array(p) if len(p) == 3 and all(map(math.isfinite, p)) else None


def parse_watch(spec):
    """The Watch a --watch value names; UserError (one line) for anything else."""
    body, at, when_s = spec.partition("@")
    when = None
    if at:
        if when_s == "max":
            when = "max"
        else:
            try:
                when = float(when_s)
            except ValueError:
                when = float("nan")
            if not (math.isfinite(when) and when >= 0):
                raise UserError(f"--watch {spec}: @{when_s}: give a time >= 0 or 'max'")
    head, colon, arg = body.partition(":")
    if head in ENERGIES and not colon:
        return Watch(spec, head, None, when)
    if head in ON_SURFACE and (not colon or arg):
        return Watch(spec, head, arg or None, when)
    if head in AT_POINT and arg:
        p = point3(arg)
        if p is None:
            raise UserError(f"--watch {spec}: {head}:X,Y,Z needs three finite coordinates")
        return Watch(spec, head, p, when)
    if head in REACTIONS and arg:
        return Watch(spec, head, arg, when)
    if head in MOMENTS and arg:
        surface, colon2, point = arg.partition(":")
        about = point3(point) if colon2 else None
        if colon2 and about is None:
            raise UserError(f"--watch {spec}: {head}:SURFACE:X,Y,Z needs three finite coordinates after the surface")
        if not surface:
            raise UserError(f"--watch {spec}: {head} needs a held SURFACE")
        return Watch(spec, head, surface, when, about)
    raise UserError(f"--watch {spec}: unknown quantity (choose from {HELP})")


def recorded_mesh(f):
    """The -mesh a run recorded in its options (None: the built-in bar or none recorded)."""
    for line in str(f.attrs.get("options", "")).splitlines():
        words = shlex.split(line) if line.strip() else []
        if len(words) == 2 and words[0] == "-mesh":
            return words[1]
    return None


def surface_nodes(f, path, surface, mesh_path=None):
    """(node ids in the output's numbering, the cells with a facet on the surface) of a physical surface
    (from the run's mesh file: `mesh_path`, else the -mesh it recorded) or a geometric selector (on the
    output's own reference mesh)."""
    out = read_mesh(path, None)                # the output's own reference mesh (its nodes, its numbering)
    if "=" in surface:
        idx = out.find(surface, "facets", "watch").items
    else:
        src = mesh_path or recorded_mesh(f)
        if not src or not os.path.isfile(src):
            raise UserError(f"--watch ...:{surface}: a physical surface needs the run's mesh file "
                            f"({'not recorded' if not src else repr(src) + ' is not there'}); use a geometric "
                            "selector (x=V, box=..., normal=+z)")
        m = read_mesh(src)
        items = m.find(surface, "facets", "watch").items
        # the same facets in the output's list (cells in the input's order; a linear mesh run at order 2 has
        # the same corners, so facet k of cell c is the same facet)
        key = {int(c) * 4 + int(k): i for i, (c, k) in enumerate(zip(out.facet_cell, out.facet_k))}
        idx = np.array([key[int(c) * 4 + int(k)] for c, k in zip(m.facet_cell[items], m.facet_k[items])])
    nodes = out.facets(idx) if out.nodes is None else out.face_nodes(idx)
    return np.unique(nodes), np.unique(out.facet_cell[idx])


def _frames(f, w, n):
    """The frame indices the Watch reads."""
    if w.when is None:
        return [n - 1]
    if w.when == "max":
        return list(range(n))
    t = f["time"][:n]
    hit = stats.at_time(t, w.when)
    if not len(hit):
        raise UserError(f"--watch {w.spec}: the run has no frame at t = {w.when:g} (frames at "
                        f"{', '.join(f'{v:g}' for v in t[:8])}{', ...' if n > 8 else ''})")
    return [int(hit[-1])]


def _pick(values, w):
    """One number of the values at the frames read: the only one, or the largest magnitude (@max)."""
    v = np.asarray(values, float)
    return float(v[np.argmax(np.abs(v))]) if w.when == "max" else float(v[-1])


def watched(path, w, mesh_path=None):
    """The value of Watch `w` in the output file `path` (mesh_path: the .msh the run read, for physical
    surfaces). UserError for what the file cannot give."""
    with h5py.File(path, "r") as f:
        if w.kind in ENERGIES:
            return _energy(f, w)
        if w.kind in REACTIONS + MOMENTS:
            return _reaction(f, w)
        n = completed_frames(f)
        if n == 0:
            raise UserError(f"--watch {w.spec}: '{path}' has no frames")
        X, tets = f["mesh/points"][:], f["mesh/tetra"][:]
        frames = _frames(f, w, n)
        if w.kind in ON_SURFACE:
            nodes, cells = surface_nodes(f, path, w.where, mesh_path) if w.where else (None, None)
            if w.kind == "max_displacement":
                vals = [np.linalg.norm((f["x"][i] - X)[nodes if nodes is not None else slice(None)], axis=1).max()
                        for i in frames]
            else:
                vals = [_cell_field(f, i, "von_mises", w)[cells if cells is not None else slice(None)].max()
                        for i in frames]
            return _pick(vals, w)
        cells, wts = locate(X, tets, w.where)
        if w.kind == "von_mises":
            return _pick([_cell_field(f, i, "von_mises", w)[int(cells[0])] for i in frames], w)
        if w.kind in STRESS:
            return _pick([_cell_field(f, i, "stress", w, STRESS[w.kind])[int(cells[0])] for i in frames], w)
        if w.kind == "pressure":
            return _pick([float(interpolate(tets, cells, wts, _point_field(f, i, "pressure", w, len(X)))[0])
                          for i in frames], w)
        vals = []
        for i in frames:
            u = interpolate(tets, cells, wts, f["x"][i] - X)[0]
            vals.append(np.linalg.norm(u) if w.kind == "point" else u[COMPONENTS[w.kind[-1]]])
        return _pick(vals, w)


def _cell_field(f, i, name, w, column=0):
    g = f.get(f"frames/{i}")
    if g is None or name not in g:
        raise UserError(f"--watch {w.spec}: frame {i} has no '{name}' field (-output_fields {name})")
    return np.asarray(g[name][:], float).reshape(len(f["mesh/tetra"]), -1)[:, column]


def _point_field(f, i, name, w, nv):
    g = f.get(f"frames/{i}")
    if g is None or name not in g or g[name].shape[0] != nv:
        raise UserError(f"--watch {w.spec}: frame {i} has no '{name}' point field (the mixed formulation writes it)")
    return np.asarray(g[name][:], float)


def _energy(f, w):
    st = stats.read(f)
    col = ENERGIES[w.kind]
    if col not in st or not len(st[col]):
        raise UserError(f"--watch {w.spec}: the run recorded no '{col}' statistics")
    return _pick(st[col][_steps(st, w)], w)


def _steps(st, w):
    """The accepted steps a Watch reads from the statistics: every one (the last read, or the largest with
    @max), or those ending at its time @T (UserError when none does)."""
    if w.when is None or w.when == "max":
        return np.flatnonzero(stats.accepted(st))
    acc = stats.accepted_at(st, w.when)
    if not len(acc):
        raise UserError(f"--watch {w.spec}: no step of the run ends at t = {w.when:g}")
    return acc


def _reaction(f, w):
    """A reaction or its moment at the end (the forces attribute) or, with @T/@max, from the statistics' force
    columns (forces.py records moments about the origin: about p, M_p = M_0 - p x F)."""
    if w.when is None:
        forces = json.loads(f.attrs["forces"])["forces"] if "forces" in f.attrs else []
        held = {r["name"]: (np.array(r["F"]), np.array(r["M"])) for r in forces if r["kind"] == "reaction"}
        vals = [held.get(w.where)]
    else:
        st = stats.read(f)
        per = [{n: (F, M) for k, n, F, M in stats.forces_of(st, i) if k == "reaction"} for i in _steps(st, w)]
        held = per[-1] if per else {}
        vals = [p.get(w.where) for p in per]
    if not held or w.where not in held:
        raise UserError(f"--watch {w.spec}: the scene holds no surface '{w.where}' (held: "
                        f"{', '.join(held) or 'none'})")
    p = np.zeros(3) if w.about is None else w.about
    vec = [M - np.cross(p, F) if w.kind in MOMENTS else F for F, M in vals]
    return _pick([np.linalg.norm(v) if w.kind in ("reaction", "moment") else v[COMPONENTS[w.kind[-1]]] for v in vec], w)
