"""What a formulation declares: one spec per formulation (formulations/NAME.py, or a folder NAME/ whose __init__.py
holds the spec), listed in formulations.REGISTRY. The model asks the spec for the system of a scene, the run for its
solver plan and its point fields, the scene reader and the option catalog for its options, `-formulation auto` for
whether it claims a scene. The base answers as the displacement formulation does (displacement.py adds nothing);
recipe for a new one: docs/design.md, "Add a formulation"."""
from dataclasses import dataclass

from ..solving.solver import SolverPlan
from ..solving.system import System


@dataclass(frozen=True)
class Problem:
    """What a formulation is asked about, once the element is decided and the mesh distributed: the scene, its
    element (element.reference.Element) and the solids some cell has, on any rank ([(where, solid)]: "the scene's",
    "region 'NAME'"; the scene's own first where some cell is in no listed region)."""
    scene: object
    element: object
    solids: tuple


class Formulation:
    name = ""
    summary = ""            # what it is, for -help and the options reference (after `NAME`:)
    rows = ()               # options of its own (core.options.Row), listed in -help after -formulation
    implied_by = ()         # options whose presence makes `-formulation auto` this one (-incompressible: mixed)
    auto_rank = 0           # -formulation auto asks the specs from the lowest rank up; the first that claims runs
    point_fields = ()       # the point fields it adds to every frame (names of output.fields.POINT_SCALARS)

    def read(self, opts, scene):
        """Read its own options into the scene (after the material and the solver options)."""

    def refusal(self, problem):
        """Why it cannot run the problem, one line naming the option (None: it can)."""
        return None

    def notes(self, problem):
        """What the start-up report says of this formulation where the user named it (-formulation NAME), one line
        each: e.g. what it gives up on this problem."""
        return []

    def claims(self, problem):
        """-formulation auto: (whether it takes the problem, a note for the start-up report or None)."""
        return True, None

    def cell_constants(self, solid):
        """The parameter block the elastic cell kernels get for a solid."""
        return solid.constants

    def system(self, problem, space, kernels, effects, constraints, x0, v0):
        """The discrete system of one step on the space (solving.system.System or a subclass)."""
        return System(space, effects, constraints, x0, v0, problem.scene.dt)

    def point_values(self, system):
        """(local positions x) -> {name: local array per node} of its point fields, for the writer; None: it has
        none."""
        return None

    def solver_plan(self, system):
        """How the Solver solves its system (solving.solver.SolverPlan)."""
        return SolverPlan()

    def describe(self, scene):
        """What the output's `formulation` attribute records."""
        return self.name
