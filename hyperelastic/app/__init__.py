"""Layer 9, app: a run put together — the Scene (every setting with its default, scene.py), the option catalog
(`-help`, the options reference, the unknown-option check; catalog.py), the model of a scene (mesh -> element ->
space -> effects -> formulation's system; model.py) and the run command (run.py)."""
