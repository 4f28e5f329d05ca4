"""Layer 2, element: the reference elements — linear (P1) and quadratic (P2) tetrahedra and their 3- and 6-node
faces, their shape functions and quadrature rules, `Element` (an order and a stiffness rule: the one argument the
element order travels as, from the model to the space and the kernels; reference.py), and integrals over facets
(faces.py). Pure numpy: no mesh, no PETSc."""
