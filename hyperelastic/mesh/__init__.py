"""Layer 3, mesh: the input mesh on one process — the mesh type with its boundary facets, physical groups and named
sets (sets.py); reading and checking any tetrahedral mesh meshio reads, quadratic meshes and their corners, spatial
ordering, point location (read.py); gmsh generation of the built-in and the user's geometries (generate.py)."""
