"""Layer 5, discretization: the distributed mesh and its unknowns — the DMPlex with the sets' labels and the P1 or
P2 vector field on it (space.py: `make_space` by the element), the compiled cell loops and their Python bindings
(kernels.py; _kernels.c with _cells.h, _material_loops.h and _element_loops.h, instantiated once per material
header of physics/materials), and the assembled tangent's exact pattern and fill (aij.py)."""
