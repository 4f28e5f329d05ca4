"""Layer 4, physics: what a scene's solid is and what acts on it, each declared once — the materials (materials/: a
Python declaration and numpy reference per material, its C kernel header, REGISTRY) and the effects (effects/:
elasticity, inertia, damping, loads, supports and Dirichlet conditions, each a Spec in REGISTRY). Nothing here
knows the element order or the mesh's distribution: an effect works on the cells and spaces it is handed."""
