"""Constitutive models, one home each: materials/NAME.py holds the numpy reference (psi(F, c), P(F, c),
dP(F, dF, c), vectorized over a leading cell axis; c the material's constants) in a class named by its
module's MATERIAL, and materials/NAME.h the C kernel (stress, derivative preparation, directional
derivative, optionally the closed-form cell tangent) that setup.py compiles into he_forces_NAME,
he_kv_NAME, ... (see _material_loops.h). A material is registered by adding NAME to REGISTRY below: its
order is the order the hard-case matrix and the help list them in.

A material declares its parameters (`Material.parameters`: name, unit, meaning, range, and how the
default follows from Young's modulus E and Poisson's ratio nu) and how its kernel constants follow from
them (`Material.constants`: the parameter block the C kernels receive, in the header's order). Every
material takes E, nu and the density rho (-E -nu -rho, or a -preset); a material with constants of its
own declares them and reads them as -NAME (per region -REGION_NAME). Units: SI.
"""
import importlib
import math
from dataclasses import dataclass, field

import numpy as np

from ...core.errors import UserError
from .base import lame

__all__ = ["COMMON", "MATERIALS", "PRESETS", "REGISTRY", "Solid", "check_parameters", "default_solid", "get",
           "lame", "own_parameters", "read_solid", "rows", "shown"]


# E [Pa], nu [-], rho [kg/m^3]: every material's
COMMON = ("E", "nu", "rho")

REGISTRY = ("linear", "stvk", "neohookean", "snh", "corotational", "mooney_rivlin", "neohookean_split", "yeoh",
            "gent", "arruda_boyce", "ogden", "hgo")
MATERIALS = {n: importlib.import_module(f".{n}", __name__).MATERIAL for n in REGISTRY}

# Preset values of the thesis framework (K. Erleben, hyper-sim, simulate/create_params.m, 2011);
# "bone" is its "cortical bone". E [Pa], nu [-], rho [kg/m^3]. Rubber is nearly incompressible: its bulk modulus,
# ~2 GPa, is some thousand times its shear modulus (Treloar, The Physics of Rubber Elasticity, 3rd ed., 1975,
# ch. 1), so nu = 0.4995 (kappa/mu = 1000: kappa = 3.3 GPa with the framework's E = 10 MPa) where the framework
# had 0.48 (kappa/mu = 25); on quadratic tetrahedra -formulation auto takes the mixed formulation for it.
PRESETS = {
    "rubber": (0.01e9, 0.4995, 1050.0),
    "steel": (210e9, 0.31, 7800.0),
    "cartilage": (0.69e6, 0.018, 1000.0),
    "cortical_bone": (16.16e9, 0.33, 1600.0),
    "bone": (16.16e9, 0.33, 1600.0),
    "cancellous_bone": (452e6, 0.3, 1600.0),
    "concrete": (30e9, 0.20, 2320.0),
    "copper": (125e9, 0.35, 8900.0),
    "aluminium": (72e9, 0.34, 2700.0),
    "glass": (50e9, 0.18, 2190.0),
}


def check_parameters(E, nu, rho, where="material"):
    for name, val in (("E", E), ("nu", nu), ("rho", rho)):
        if not math.isfinite(val):
            raise UserError(f"{where}: -{name} {val} is not a finite number")
    if E <= 0:
        raise UserError(f"{where}: Young's modulus -E {E:g} must be > 0")
    if not (-1 < nu < 0.5):
        raise UserError(f"{where}: Poisson's ratio -nu {nu:g} must satisfy -1 < nu < 0.5")
    if rho <= 0:
        raise UserError(f"{where}: density -rho {rho:g} must be > 0")


def shown(v):
    """A parameter's value as the set report and -help show it: a number, a vector's x,y,z, or a field's text."""
    if isinstance(v, CellField):
        return f"'{v.text}'"
    return ",".join(f"{x:g}" for x in v) if isinstance(v, (tuple, list)) else f"{v:g}"


class CellField:
    """A vector parameter given per cell: three expressions of the reference coordinates X, Y, Z (`-fibre1 'EX,EY,EZ'`,
    commas inside parentheses belong to the expression) at each cell's reference centroid, or (MeshField) a cell data
    array of the mesh file (`-fibre1 mesh:NAME`); a direction field is made unit per cell (Solid.localized)."""

    def __init__(self, text, option):
        from ...core.expressions import Expression
        self.text, self.option = text, option
        parts = split_top(text)
        if len(parts) != 3:
            raise UserError(f"option -{option}: '{text[:80]}' is not three numbers nor three expressions of X, Y, Z "
                            f"(got {len(parts)} parts; e.g. '-sin(atan2(Y,X)),cos(atan2(Y,X)),0')")
        self.exprs = [Expression(t, ("X", "Y", "Z"), where=f"option -{option}") for t in parts]

    def at(self, P):
        """(n, 3) of the field at points P (n, 3); UserError naming the first point where it is not finite."""
        with np.errstate(all="ignore"):
            env = {"X": P[:, 0], "Y": P[:, 1], "Z": P[:, 2]}
            v = np.stack([np.broadcast_to(np.asarray(e._eval(e.tree, env), np.float64), len(P)) for e in self.exprs],
                         axis=1)
        bad = np.flatnonzero(~np.isfinite(v).all(axis=1))
        if len(bad):
            raise UserError(f"option -{self.option}: '{self.text[:80]}' is not finite at the cell centred at "
                            f"{','.join(f'{c:.6g}' for c in P[bad[0]])}")
        return v


class MeshField(CellField):
    """`-PARAM mesh:NAME`: the mesh file's cell data NAME, a row of `size` numbers per tetrahedron (gmsh's
    $ElementData, a .vtu's CellData: anything meshio reads), taken by each cell from its input cell (a cell made by
    -refine from its parent's)."""

    def __init__(self, text, option):
        self.text, self.option, self.name = text, option, text.split(":", 1)[1].strip()
        if not self.name:
            raise UserError(f"option -{option}: '{text}' names no cell data (mesh:NAME)")


def split_top(text):
    """text split at its commas outside parentheses."""
    parts, depth, cur = [], 0, ""
    for ch in text:
        depth += (ch == "(") - (ch == ")")
        if ch == "," and depth == 0:
            parts.append(cur)
            cur = ""
        else:
            cur += ch
    return parts + [cur]


def get(name):
    try:
        return MATERIALS[name]
    except KeyError:
        raise UserError(f"unknown material '{name}' (choose from {', '.join(sorted(MATERIALS))})") from None


def own_parameters():
    """{parameter name: Parameter} of every material (a name several materials declare means the same)."""
    out = {}
    for m in MATERIALS.values():
        for p in m.parameters:
            out.setdefault(p.name, p)
    return out


@dataclass
class Solid:
    """A material with its parameters resolved: the scene's, or a region's (-regions)."""
    material: type                               # a Material subclass
    values: dict = field(default_factory=dict)   # E, nu and the material's own parameters
    rho: float = 1000.0

    @property
    def name(self):
        return self.material.name

    @property
    def constants(self):
        """The kernels' parameter block: a tuple, or a row per cell where a parameter is a field (`localized`)."""
        c = self.material.constants(self.values)
        return c if np.ndim(c) == 2 else tuple(float(x) for x in c)

    @property
    def fields(self):
        """The names of its parameters given as fields (CellField)."""
        return [k for k, v in self.values.items() if isinstance(v, CellField)]

    def localized(self, P, rows=None):
        """The solid on cells with reference centroids P (n, 3): each field parameter a direction per cell (an (n, 3)
        array, which the material makes unit; UserError at the first cell where it has no length); rows: {parameter:
        (n, 3)} of the mesh fields (MeshField) on these cells. Itself where it has no field."""
        if not self.fields:
            return self
        values = dict(self.values)
        for k in self.fields:
            v = rows[k] if isinstance(values[k], MeshField) else values[k].at(P)
            n = np.linalg.norm(v, axis=1)
            if len(n) and not (np.isfinite(n) & (n > 0)).all():
                i = int(np.flatnonzero(~(np.isfinite(n) & (n > 0)))[0])
                raise UserError(f"option -{values[k].option}: '{values[k].text[:80]}' is no direction at the cell "
                                f"centred at {','.join(f'{c:.6g}' for c in P[i])} (its length is 0 or not finite)")
            values[k] = v
        return Solid(self.material, values, self.rho)

    def describe(self):
        """One line of the material and its parameters, as the set report prints it."""
        own = "".join(f", {p.name} {shown(self.values[p.name])}" for p in self.material.parameters)
        return f"{self.material.name}, E {self.values['E']:g}, nu {self.values['nu']:g}{own}, rho {self.rho:g}"

    def record(self):
        """The parameters as the output records them (JSON-able)."""
        return {"material": self.material.name, "rho": self.rho,
                **{k: v.text if isinstance(v, CellField) else [float(x) for x in v] if isinstance(v, (tuple, list))
                   else float(v) for k, v in self.values.items()}}


def read_solid(opts, prefix, default, where):
    """The Solid of -PREFIXmaterial, -PREFIXpreset, -PREFIXE, -PREFIXnu, -PREFIXrho and the material's own
    -PREFIXNAME over `default` (a Solid: the scene's, for a region), validated. A material parameter not
    given follows from E and nu by its declaration; for a region, the un-prefixed option where given."""
    text = opts.string(f"{prefix}material", None)
    try:
        mat = default.material if text is None else get(text)
    except UserError as e:
        raise UserError(f"option -{prefix}material: {e}") from None
    preset = opts.string(f"{prefix}preset", None)
    E, nu, rho = default.values["E"], default.values["nu"], default.rho
    if preset is not None:
        if preset not in PRESETS:
            raise UserError(f"option -{prefix}preset: unknown preset '{preset}' (choose from "
                            f"{', '.join(sorted(PRESETS))})")
        E, nu, rho = PRESETS[preset]
    E, nu, rho = opts.real(f"{prefix}E", E), opts.real(f"{prefix}nu", nu), opts.real(f"{prefix}rho", rho)
    check_parameters(E, nu, rho, where=where)
    values, keys = {"E": E, "nu": nu}, {}
    values.update(_lists(opts, prefix, mat))
    for p in mat.parameters:                           # the given ones first: defaults may follow from them
        if p.name in values:
            continue
        keys[p.name] = f"{prefix}{p.name}" if opts.has(f"{prefix}{p.name}") or not opts.has(p.name) else p.name
        v = _vector(opts, keys[p.name], p) if p.size > 1 else opts.real(keys[p.name], None)   # (a region's default:
        if v is not None:                                                                  # the un-prefixed option)
            values[p.name] = tuple(v) if p.size > 1 and not isinstance(v, CellField) else v
    for p in mat.parameters:
        given = p.name in values
        if not given:
            values[p.name] = p.default(values)
        if p.size > 1:
            continue
        if values[p.name] <= p.minimum if p.exclusive else values[p.name] < p.minimum:
            what = (f"-{keys[p.name]} {values[p.name]:g}" if given else
                    f"{p.name} = {values[p.name]:g} (from {p.default_text})")
            raise UserError(f"{where}: {what} must be {'>' if p.exclusive else '>='} {p.minimum:g} ({p.meaning})")
    mat.check(values, where)
    return Solid(mat, values, rho)


def _lists(opts, prefix, mat):
    """{parameter: value} of the material's list options (Material.list_options: -ogden_mu a,b,c gives mu1..mu3),
    one line where a list is too long or a parameter it gives is also given alone."""
    out = {}
    for name, params in mat.list_options.items():
        key = f"{prefix}{name}" if opts.has(f"{prefix}{name}") or not opts.has(name) else name
        vals = opts.numbers(key, len(params), "0.63e6,0.0012e6,-0.01e6")
        if vals is None:
            continue
        both = [p for p in params[:len(vals)] if opts.has(f"{prefix}{p}")]
        if both:
            raise UserError(f"option -{key} gives {both[0]}, and so does -{prefix}{both[0]}: give the terms one way")
        out.update(zip(params, vals))
    return out


def _vector(opts, key, p):
    """A vector parameter's value: its numbers, or (a parameter that may vary per cell: Parameter.field) a CellField
    where they are expressions of X, Y, Z."""
    text = opts.string(key, None)
    if text is None or not p.field:
        return opts.vector(key, p.size)
    try:
        return opts.vector(key, p.size)
    except UserError:
        if all(_number(t) for t in text.replace(";", ",").split(",")):
            raise                               # (numbers, not p.size of them, or too large: the vector's line)
        return MeshField(text, key) if text.strip().startswith("mesh:") else CellField(text, key)


def _number(text):
    try:
        float(text)
        return True
    except ValueError:
        return False


def default_solid(name, E=1e6, nu=0.3, rho=1000.0):
    """Material `name` at (E, nu, rho), its own constants following from them (their defaults)."""
    m = get(name)
    values = {"E": E, "nu": nu}
    for p in m.parameters:
        values[p.name] = p.default(values)
    return Solid(m, values, rho)


def rows():
    """The catalog rows of the materials' own parameters (one per material that has any)."""
    from ...core.options import Row      # deferred: it imports petsc4py, which `hyperelastic fit` does without
    out = []
    for m in MATERIALS.values():
        if not m.parameters:
            continue
        names = tuple(p.name for p in m.parameters) + tuple(m.list_options)
        help_ = f"`{m.name}`'s constants: " + "; ".join(f"{p.name} [{p.unit}] {p.meaning}" for p in m.parameters)
        for name, params in m.list_options.items():
            help_ += f"; {name}: {params[0]}..{params[-1]} as a list"
        if m.references:
            help_ += f" ({m.references})"
        help_ += "; per region `-R1_" + "`, `-R1_".join(names) + "`"
        out.append(Row(names, " ".join(f"-{n}" for n in names), help_,
                       "; ".join(f"{p.name} = {p.default_text}" for p in m.parameters)))
    return out
