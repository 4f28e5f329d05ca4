"""Any number of loads, each named in -loads and read with its name as option prefix: its kind (-NAME_KIND VALUE, one
of the effects that declare a LoadKind: traction, pressure, force, spring), its surfaces -NAME_faces and its time
function -NAME_time or -NAME_ramp. Each is built by its kind's own Spec. The kinds are not listed here: `spec(kinds)`
makes the loads' Spec from the effects that declare one (effects/__init__.py), so a new kind is a `load=LoadKind(...)`
in its effect's Spec."""
from dataclasses import dataclass

from ...core.errors import UserError
from ...core.options import Row, facet_sets, needs, prefixed_names, time_function
from .base import Spec


@dataclass(frozen=True)
class Load:
    name: str
    kind: str         # the name of the effect whose LoadKind it is
    value: object     # a vector (traction [Pa], force [N]) or a number (pressure [Pa], spring [Pa/m])
    faces: tuple      # ((set name, components), ...)
    scale: object     # time function (base.load_factor); None for a kind without one (a spring)


@dataclass(frozen=True)
class Loads:
    items: tuple      # Load

    @property
    def names(self):
        return [ld.name for ld in self.items]


def _read_one(opts, name, kinds):
    given = [k for k in kinds if opts.has(f"{name}_{k}")]
    if len(given) != 1:
        raise UserError(f"load '{name}': give one of " + ", ".join(f"-{name}_{k}" for k in kinds)
                        + (f" (not {' and '.join('-' + name + '_' + k for k in given)})" if given else ""))
    kind = given[0]
    how = kinds[kind]
    if not opts.has(f"{name}_faces"):
        raise UserError(f"load '{name}': needs -{name}_faces (physical surface names or tags, or box faces)")
    if not how.timed and (opts.has(f"{name}_time") or opts.has(f"{name}_ramp")):
        raise UserError(f"load '{name}': a {kind} has no time function (-{name}_time, -{name}_ramp)")
    key = f"{name}_{kind}"
    if how.value == "vector":
        value = tuple(opts.vector(key))
    else:
        value = opts.real(key) if how.minimum is None else opts.real(key, minimum=how.minimum)
    scale = time_function(opts, name) if how.timed else None
    return Load(name, kind, value, tuple(facet_sets(opts, f"{name}_faces", components=how.components)), scale)


def spec(kind_specs):
    """The Spec of -loads whose kinds are the effects `kind_specs` (each with its `load`, a base.LoadKind)."""
    kinds = {s.name: s.load for s in kind_specs}
    builders = {s.name: s.build for s in kind_specs}

    def read(opts, where):
        out = tuple(_read_one(opts, name, kinds) for name in prefixed_names(opts, "loads"))
        if not out:
            names = [f"-NAME_{k}" for k in kinds]
            raise needs(where, "loads", f"-loads NAME,... with {', '.join(names[:-1])} or {names[-1]} and -NAME_faces")
        return Loads(out)

    def build(p, ctx):
        return [e for ld in p.items for e in builders[ld.kind](kinds[ld.kind].params(ld.value, ld.faces, ld.scale),
                                                                ctx)]

    helps = [k.help for k in kinds.values()]
    energies = {e.column: e for s in kind_specs for e in s.energies}
    return Spec(
        "loads", "named loads, each with its kind, surfaces and time function", implied_by=("loads",), read=read,
        sets=lambda p: [(f"{ld.name}_faces", n, "facets") for ld in p.items for n, _ in ld.faces], build=build,
        energies=tuple(energies.values()),
        rows=(Row(("loads",) + tuple(f"LOAD_{k}" for k in kinds) + ("LOAD_faces", "LOAD_time", "LOAD_ramp"),
                  "-loads L1,L2,…", "any number of loads, each with its own surfaces and time function: "
                  + ", ".join(helps[:-1]) + f" or {helps[-1]}, `-L1_faces S1,…`, `-L1_time EXPR` or `-L1_ramp A`"),))
