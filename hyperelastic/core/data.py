"""Where the package's own data lies (hyperelastic/data, installed with the package, found from any working
directory): the solver recipes (`-options_file NAME.opts`), the built-in scenes and the built-in geometries.
No PETSc here: the command line looks these up before PETSc reads its arguments."""
import os

DATA_DIR = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "data")
OPTIONS_DIR = os.path.join(DATA_DIR, "options")           # solver recipes NAME.opts
SCENES_DIR = os.path.join(OPTIONS_DIR, "scenes")          # built-in scenes NAME.opts
GEO_DIR = os.path.join(DATA_DIR, "meshes")                # built-in geometries NAME.geo (the thesis' bar)


def cache_dir(kind=""):
    """Where this application keeps what it can make again (generated meshes of the built-in geometries; `kind`
    "parsed": checked meshes): $HYPERELASTIC_MESH_CACHE, else the user's cache ($XDG_CACHE_HOME or ~/.cache,
    /hyperelastic/meshes); never inside the installed package. Made on first use."""
    user = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    d = os.environ.get("HYPERELASTIC_MESH_CACHE") or os.path.join(user, "hyperelastic", "meshes")
    d = os.path.join(d, kind) if kind else d
    os.makedirs(d, exist_ok=True)
    return d


def builtin_scenes():
    return sorted(f[:-5] for f in os.listdir(SCENES_DIR) if f.endswith(".opts"))


def recipes():
    return sorted(f[:-5] for f in os.listdir(OPTIONS_DIR) if f.endswith(".opts"))


def recipe_path(arg):
    """The package's recipe an `-options_file` argument names where it is not a file here: `gamg`, `gamg.opts` or
    `options/gamg.opts` (the guide's spelling, from any directory); None when it names none."""
    if os.path.exists(arg):
        return None
    name = os.path.basename(arg)
    name = name[:-5] if name.endswith(".opts") else name
    if os.path.dirname(arg) not in ("", "options") or name not in recipes():
        return None
    return os.path.join(OPTIONS_DIR, name + ".opts")
