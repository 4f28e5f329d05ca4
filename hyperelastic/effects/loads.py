"""Any number of loads, each named in -loads and read with its name as option prefix: its kind (one of
-NAME_traction, -NAME_pressure, -NAME_force, -NAME_spring), its surfaces -NAME_faces and its time function
-NAME_time or -NAME_ramp. Each is built as the effect of its kind (traction.py, pressure.py, force.py,
spring.py); a new kind is a line in KINDS."""
from dataclasses import dataclass

from ..errors import UserError
from ..options import Row, facet_sets, needs, prefixed_names, time_function
from .base import Spec
from .force import Force
from .pressure import pressure
from .spring import SPEC as SPRING, build_spring
from .traction import TRACTION_WORK, Traction


def _traction(ld, ctx, tris):
    return Traction(ctx.space.X, tris, ld.value, ld.scale, ctx.space.nlv)


def _pressure(ld, ctx, tris):
    return pressure(ctx.space.X, tris, ld.value, ld.scale)


def _force(ld, ctx, tris):
    return Force(ctx.space.X, tris, ld.value, ld.scale, ctx.space.nlv, ctx.space.mpi)


# kind: (how its value is read: "vector" | "real", whether its faces name components, its builder from the
# load, the context and its triangles (None: builds from the faces itself))
KINDS = {
    "traction": ("vector", False, _traction),
    "pressure": ("real", False, _pressure),
    "force": ("vector", False, _force),
    "spring": ("real", True, None),
}


@dataclass(frozen=True)
class Load:
    name: str
    kind: str         # a key of KINDS
    value: object     # a vector (traction [Pa], force [N]) or a number (pressure [Pa], spring [Pa/m])
    faces: tuple      # ((set name, components), ...)
    scale: object     # time function (base.load_factor); None for a spring


@dataclass(frozen=True)
class Loads:
    items: tuple      # Load

    @property
    def names(self):
        return [ld.name for ld in self.items]


def _read_one(opts, name):
    given = [k for k in KINDS if opts.has(f"{name}_{k}")]
    if len(given) != 1:
        raise UserError(f"load '{name}': give one of " + ", ".join(f"-{name}_{k}" for k in KINDS)
                        + (f" (not {' and '.join('-' + name + '_' + k for k in given)})" if given else ""))
    kind = given[0]
    how, components, _ = KINDS[kind]
    if not opts.has(f"{name}_faces"):
        raise UserError(f"load '{name}': needs -{name}_faces (physical surface names or tags, or box faces)")
    if kind == "spring":
        if opts.has(f"{name}_time") or opts.has(f"{name}_ramp"):
            raise UserError(f"load '{name}': a spring has no time function (-{name}_time, -{name}_ramp)")
        value, scale = opts.real(f"{name}_spring", minimum=0), None
    else:
        value = tuple(opts.vector(f"{name}_{kind}")) if how == "vector" else opts.real(f"{name}_{kind}")
        scale = time_function(opts, name)
    return Load(name, kind, value, tuple(facet_sets(opts, f"{name}_faces", components=components)), scale)


def _read(opts, where):
    out = tuple(_read_one(opts, name) for name in prefixed_names(opts, "loads"))
    if not out:
        raise needs(where, "loads", "-loads NAME,... with -NAME_traction, -NAME_pressure, -NAME_force or "
                    "-NAME_spring and -NAME_faces")
    return Loads(out)


def _build(p, ctx):
    out = []
    for ld in p.items:
        build = KINDS[ld.kind][2]
        if build is None:
            out.append(build_spring(ld.value, ld.faces, ctx))
        else:
            out.append(build(ld, ctx, ctx.space.set_triangles([n for n, _ in ld.faces])))
    return out


SPEC = Spec(
    "loads", "named loads, each with its kind, surfaces and time function", implied_by=("loads",), read=_read,
    sets=lambda p: [(f"{ld.name}_faces", n, "facets") for ld in p.items for n, _ in ld.faces], build=_build,
    energies=(TRACTION_WORK,) + SPRING.energies,
    rows=(Row(("loads", "LOAD_traction", "LOAD_pressure", "LOAD_force", "LOAD_spring", "LOAD_faces", "LOAD_time",
               "LOAD_ramp"), "-loads L1,L2,…",
              "any number of loads, each with its own surfaces and time function: `-L1_traction tx,ty,tz` (dead, "
              "per reference area), `-L1_pressure p` (follower), `-L1_force Fx,Fy,Fz` (total, dead) or "
              "`-L1_spring k` (elastic support; faces may name components, no time function), `-L1_faces S1,…`, "
              "`-L1_time EXPR` or `-L1_ramp A`"),))
