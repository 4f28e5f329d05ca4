"""Layer 6, solving: one step's discrete system and how it is solved — R(x), J(x), the Dirichlet elimination and the
incremental potential (system.py), the Jacobian operators (jacobians.py), SNES/KSP/PC with this application's
defaults and a formulation's solver plan (solver.py), backward Euler with step control (integrators.py) and PETSc
TS (ts_integrator.py), the statistics columns (stats.py) and the forces on the body's surfaces (forces.py)."""
