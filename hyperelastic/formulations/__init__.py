"""Layer 8, formulations: the systems of equations a run solves, one declared spec per file (base.py: what a spec
declares; displacement.py; mixed/), listed in REGISTRY; `-formulation auto` asks each in turn (choose)."""
from ..core.errors import UserError
from . import displacement, mixed

REGISTRY = (displacement.FORMULATION, mixed.FORMULATION)
SPECS = {f.name: f for f in REGISTRY}
NAMES = ("auto",) + tuple(SPECS)


def choose(problem):
    """(the formulation that runs the problem, [notes for the start-up report]). `-formulation NAME`: that one, or
    its one-line refusal; `auto`: the first spec, by auto_rank, that claims the problem (each may add a note)."""
    name = problem.scene.formulation
    if name != "auto":
        spec = SPECS[name]
        why = spec.refusal(problem)
        if why:
            raise UserError(why)
        return spec, spec.notes(problem)
    notes = []
    for spec in sorted(REGISTRY, key=lambda f: f.auto_rank):
        take, note = spec.claims(problem)
        if note:
            notes.append(note)
        if take:
            return spec, notes
    raise AssertionError("no formulation claims the problem (the displacement formulation claims every one)")


def rows():
    """The option rows of the formulations' own options (-help, the options reference)."""
    return tuple(r for f in REGISTRY for r in f.rows)
