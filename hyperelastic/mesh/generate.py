"""gmsh generation: the built-in geometries (the thesis' bar, at levels L1..L8 and finer) and a user's .geo/.step
part, meshed at a target edge length, linear or quadratic, optionally refined; the built-in bar's meshes cached on
first use. Every mesh written is read back and checked (read.py) before it is moved into place."""
import math
import os
import re

import numpy as np

from ..core.data import GEO_DIR, cache_dir
from ..core.arrays import unique
from ..core.errors import UserError
from ..core.files import check_output_path
from ..element.reference import ORDERS
from .read import _quiet, read_mesh

# Target edge lengths L1..L8 of the thesis (Table 4); finer levels halve the tet volume each step
# (edge length / 2^(1/3)), so each level has about twice the tets of the one before.
LEVEL_SIZES = {1: 0.80, 2: 0.75, 3: 0.65, 4: 0.50, 5: 0.45, 6: 0.40, 7: 0.35, 8: 0.30}


MAX_LEVEL = 14     # ~64x the tets of L8: beyond, gmsh would run for hours on this kind of machine


def level_size(level):
    if level < 1:
        raise UserError(f"mesh level {level} must be >= 1")
    if level > MAX_LEVEL:
        raise UserError(f"mesh level {level}: levels go up to {MAX_LEVEL} (~2x the tets per level; for a finer "
                        "mesh give -mesh FILE)")
    if level in LEVEL_SIZES:
        return LEVEL_SIZES[level]
    return LEVEL_SIZES[8] * 2.0 ** (-(level - 8) / 3.0)


CAD_SUFFIXES = (".geo", ".step", ".stp", ".brep", ".iges", ".igs")


def geometry_file(name):
    """The geometry a `mesh` command names: a user's .geo/.step/.brep file, or meshes/<name>.geo."""
    if name.lower().endswith(CAD_SUFFIXES):
        if not os.path.isfile(name):
            raise UserError(f"geometry '{name}': no such file")
        return name
    geo = os.path.join(GEO_DIR, f"{name}.geo")
    if not os.path.isfile(geo):
        known = sorted(f[:-4] for f in os.listdir(GEO_DIR) if f.endswith(".geo"))
        raise UserError(f"unknown mesh geometry '{name}' (known: {', '.join(known)}; or give a .geo or .step file)")
    return geo


def generate(name, level, out, size=None, refine=0, order=1, graded=False):
    """Mesh a geometry (meshes/<name>.geo, or a user's .geo/.step file) with gmsh at the target edge
    length of `level` (or `size` when given), keeping its physical groups; returns its statistics.
    graded: the geometry's own sizes (its background field, its points' characteristic lengths) are kept, `size`
    being the largest edge (gmsh's Mesh.MeshSizeMax); otherwise every edge is `size` (MeshSizeMin = Max), and
    the statistics' `flattened` says whether the geometry declared a size field that this overrode.
    With refine = N, also N uniformly refined meshes (each tet split into 8), OUT_r1.msh ... OUT_rN.msh,
    and returns a list of statistics. order 2: 10-node tetrahedra (and 6-node triangles), their edge nodes
    placed on the geometry where it is curved (gmsh's high-order meshing). Every mesh is written to a temporary
    file, read back and checked, and only then renamed into place: nothing of a failed run stays behind."""
    if order not in ORDERS:
        raise UserError(f"hyperelastic mesh: --order {order}: give 1 or 2")
    geo = geometry_file(name)
    if size is None:
        size = level_size(level)
    elif not (size > 0 and math.isfinite(size)):
        raise UserError(f"mesh size {size} must be a finite number > 0")
    outs = _outputs(out, refine)
    import gmsh    # deferred on purpose: loading gmsh's library takes ~0.3 s, and only meshing needs it
    # interruptible=False: gmsh's Python API would set SIGINT to SIG_DFL and (its finalize restoring a global it
    # never set) leave it so: Ctrl-C would then kill a study outright, with no report and its child run orphaned
    gmsh.initialize(["gmsh", "-v", "0"], readConfigFiles=False, interruptible=False)
    tmps = []
    try:
        auto_named, flattened = _mesh(gmsh, name, geo, size, refine, graded)
        groups, extent = physical_groups(gmsh, geo)
        for i, o in enumerate(outs):
            if i:
                if order > 1:
                    gmsh.model.mesh.setOrder(1)          # refine the linear mesh, then place the new edge nodes
                gmsh.model.mesh.refine()
            if order > 1:
                gmsh.model.mesh.setOrder(order)
            tmps.append(o + f".tmp{os.getpid()}.msh")
            gmsh.write(tmps[-1])
        gmsh.finalize()
        meshes = _read_back(outs, tmps, size)
    except BaseException:  # nothing of a failed run stays behind
        if gmsh.isInitialized():
            gmsh.finalize()
        for tmp in tmps:
            if os.path.exists(tmp):
                os.remove(tmp)
        raise
    stats = []
    for i, (o, tmp, m) in enumerate(zip(outs, tmps, meshes)):
        os.replace(tmp, o)
        stats.append(describe(m.points, m.tets) | {"level": level, "target_size": size / 2 ** i, "file": o,
                                                   "vertices": len(unique(m.tets)), "nodes": len(m.points),
                                                   "order": m.order, "auto_named": auto_named,
                                                   "graded": graded, "flattened": flattened,
                                                   "surfaces": surface_rows(m) if i == 0 else [],
                                                   "groups": groups, "extent": extent})
    return stats if refine else stats[0]


def _outputs(out, refine):
    """OUT and its refinements' OUT_r1.msh ... OUT_rN.msh, each a .msh path that may be written."""
    outs = [out] + [f"{os.path.splitext(out)[0]}_r{i}.msh" for i in range(1, refine + 1)]
    for o in outs:
        if not o.lower().endswith(".msh"):
            raise UserError(f"hyperelastic mesh: -o '{o}' must end in .msh (gmsh's format is what it writes)")
        check_output_path(o, suffixes=None)
    return outs


def _mesh(gmsh, name, geo, size, refine, graded=False):
    """Open the geometry in gmsh and mesh its volumes at edge length `size` (graded: the geometry's own sizes, at
    most `size`); returns (whether its surfaces and volumes were named by their tags (_name_entities), whether
    a size field of the geometry was overridden by the uniform size)."""
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.option.setNumber("General.NumThreads", 1)
    try:
        _quiet(gmsh.open, geo)
    except Exception as e:
        raise UserError(f"geometry '{name}': gmsh cannot read it ({str(e).strip()[:200]})") from None
    _check_size(gmsh, name, size, refine)
    auto_named = _name_entities()
    fields = len(gmsh.model.mesh.field.list()) > 0
    sizes = (("MeshSizeMax", size),) if graded else (("MeshSizeMin", size), ("MeshSizeMax", size),
                                                      ("MeshSizeExtendFromBoundary", 0))
    for key, value in sizes + (("Algorithm3D", 1), ("ElementOrder", 1), ("MshFileVersion", 4.1), ("SaveAll", 0)):
        gmsh.option.setNumber(f"Mesh.{key}", value)
    if graded:
        _check_graded(gmsh, name, size, refine)
    try:
        gmsh.model.mesh.generate(3)
    except Exception as e:
        raise UserError(f"geometry '{name}': gmsh cannot mesh it ({str(e).strip()[:200]})") from None
    if not len(gmsh.model.mesh.getElementTypes(3)):
        raise UserError(f"geometry '{name}': gmsh made no tetrahedra (a 2-D geometry, or surfaces that do not "
                        "close a volume)")
    return auto_named, fields and not graded


DECLARED = re.compile(r'Physical\s+(Surface|Volume)\s*\(\s*"([^"]+)"')


def physical_groups(gmsh, geo):
    """([(kind, name, entities)] of the geometry's physical groups, surfaces and volumes: those gmsh holds, and
    those a .geo declares by name (`Physical Surface("clamp", 1) = ...`) that gmsh does not hold because their list
    came out empty (0 entities); and the geometry's extent (its bounding box's diagonal)."""
    out = []
    for dim, tag in gmsh.model.getPhysicalGroups():
        if dim in (2, 3):
            name = gmsh.model.getPhysicalName(dim, tag) or str(tag)
            out.append(("surface" if dim == 2 else "volume", name,
                        len(gmsh.model.getEntitiesForPhysicalGroup(dim, tag))))
    if geo.lower().endswith(".geo"):
        held = {(kind, name) for kind, name, _ in out}
        with open(geo, encoding="utf-8", errors="replace") as fh:
            for kind, name in DECLARED.findall(fh.read()):
                if (kind.lower(), name) not in held:
                    out.append((kind.lower(), name, 0))
                    held.add((kind.lower(), name))
    box = np.array(gmsh.model.getBoundingBox(-1, -1))
    return out, float(np.linalg.norm(box[3:] - box[:3]))


def empty_group_lines(groups, extent):
    """One warning line per physical group that holds nothing (gmsh writes no such group: a run naming it fails
    later), with what usually causes it."""
    return [f"warning: physical {kind} '{name}' holds no {kind} of the geometry and is not in the mesh (a "
            f"selection such as 'In BoundingBox' that caught nothing: its tolerance or coordinates may not fit a part "
            f"{extent:.3g} across, in the geometry's units)" for kind, name, n in groups if n == 0]


def _read_back(outs, tmps, size):
    """Every written mesh read back and checked (before any is renamed into place)."""
    meshes = []
    for i, (o, tmp) in enumerate(zip(outs, tmps)):
        try:
            meshes.append(read_mesh(tmp))
        except UserError as e:
            why = (f" (gmsh's refinement moves the new nodes of curved surfaces onto the geometry, which crosses "
                   f"tets this coarse: give a --size below {size:g})") if i else ""
            raise UserError(str(e).replace(tmp, o) + why) from None
    return meshes


def _name_entities():
    """A geometry without physical groups (a STEP file, a bare .geo): every surface and volume of it becomes
    a physical group named by its tag (surface_12, volume_1), so the mesh keeps them and runs can use them.
    Returns whether it did."""
    import gmsh
    if gmsh.model.getPhysicalGroups():
        return False
    for dim, kind in ((2, "surface"), (3, "volume")):
        for _, tag in gmsh.model.getEntities(dim):
            gmsh.model.setPhysicalName(dim, gmsh.model.addPhysicalGroup(dim, [tag], tag), f"{kind}_{tag}")
    return True


def surface_rows(m):
    """[(name, facets, area, centroid, normal)] of a mesh's named surfaces (sets.Mesh): the outward unit
    normal where the surface is planar (every facet's within 1e-6), else None."""
    rows = []
    for g in m.groups.values():
        if g.kind != "facets" or not len(g.items):
            continue
        tri = m.points[m.facets(g.items)]
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]) / 2
        a = np.linalg.norm(n, axis=1)
        centroid = (tri.mean(axis=1) * a[:, None]).sum(axis=0) / a.sum()
        unit = n.sum(axis=0) / np.linalg.norm(n.sum(axis=0))
        planar = np.all(n @ unit >= (1 - 1e-6) * a)
        rows.append((g.name, len(g.items), m.area(g.items), centroid, unit if planar else None))
    return rows


def format_normal(u):
    if u is None:
        return "(not planar)"
    k = int(np.argmax(np.abs(u)))
    if abs(abs(u[k]) - 1) < 1e-9:
        return f"{'+' if u[k] > 0 else '-'}{'xyz'[k]}"
    return "(" + ", ".join(f"{c:.4g}" for c in u) + ")"


MAX_TETS = 2e8      # beyond, gmsh would run for hours and the mesh would not fit this kind of machine


# the largest mesh size taken, in units of the geometry's extent (its bounding box's diagonal): beyond, the "mesh"
# would be the corners alone, and a size that large is a typo or a unit mistake
MAX_SIZE_PER_EXTENT = 100.0


def _check_size(gmsh, name, size, refine):
    """UserError when the opened geometry is empty, when `size` is over MAX_SIZE_PER_EXTENT times its extent, or
    when edge length `size` (and `refine` refinements, 8x each) would give more than MAX_TETS tetrahedra: its
    bounding box's volume over a regular tetrahedron's (an upper estimate for a solid part)."""
    try:
        x0, y0, z0, x1, y1, z1 = gmsh.model.getBoundingBox(-1, -1)
    except Exception:       # gmsh: "Empty bounding box"
        raise UserError(f"geometry '{name}': holds no geometry (an empty or unreadable file)") from None
    extent = math.sqrt(max(x1 - x0, 0.0) ** 2 + max(y1 - y0, 0.0) ** 2 + max(z1 - z0, 0.0) ** 2)
    if size > MAX_SIZE_PER_EXTENT * extent:
        raise UserError(f"mesh size {size:g} is over {MAX_SIZE_PER_EXTENT:g} times the geometry's extent (bounding "
                        f"box {x1 - x0:.3g} x {y1 - y0:.3g} x {z1 - z0:.3g}): give one in the geometry's units")
    volume = max(x1 - x0, 0.0) * max(y1 - y0, 0.0) * max(z1 - z0, 0.0)
    cell = size ** 3 / (6 * math.sqrt(2))
    estimate = volume / cell * 8 ** refine if cell > 0 else math.inf
    if estimate > MAX_TETS:
        raise UserError(f"geometry '{name}': mesh size {size:g} would make up to ~{estimate:.2g} tetrahedra "
                        f"(bounding box {x1 - x0:.3g} x {y1 - y0:.3g} x {z1 - z0:.3g}); give a size that makes at most "
                        f"{MAX_TETS:.0e}")


PROBE_TETS = 2e4      # the coarse probe mesh of a graded geometry's size field (_check_graded): ~0.1-0.2 s


def _check_graded(gmsh, name, size, refine):
    """UserError when the geometry's own sizes (its size fields, its points' lengths; --graded) would make more than
    MAX_TETS tetrahedra: gmsh meshes the part coarsely (PROBE_TETS, uniform) while a size callback records the size
    the geometry asks for at each point it evaluates in the volume; the estimate sums the volume each point stands for
    over a regular tetrahedron of that size (a field asking 0.002 in a unit cube: 1.06e9, its 8.485/h^3 exactly; a
    graded one: 20k where gmsh made 9.4k). _check_size sees --size alone: such a geometry ran gmsh unbounded."""
    x0, y0, z0, x1, y1, z1 = gmsh.model.getBoundingBox(-1, -1)
    volume = max(x1 - x0, 0.0) * max(y1 - y0, 0.0) * max(z1 - z0, 0.0)
    regular = 6 * math.sqrt(2)                      # a regular tetrahedron of edge h has volume h^3 / regular
    probe = (volume * regular / PROBE_TETS) ** (1 / 3)
    asked = []

    def record(dim, tag, x, y, z, lc):
        if dim == 3:
            asked.append(lc)
        return max(lc, probe)
    gmsh.model.mesh.setSizeCallback(record)
    try:
        _quiet(gmsh.model.mesh.generate, 3)
    except Exception:
        return                                      # (the real meshing below says what gmsh cannot do)
    finally:
        gmsh.model.mesh.removeSizeCallback()
        gmsh.model.mesh.clear()
    lc = np.asarray(asked, float)
    lc = lc[np.isfinite(lc) & (lc > 0)]
    if not len(lc):
        return
    estimate = volume / len(lc) * float(np.sum(regular / lc ** 3)) * 8 ** refine
    if estimate > MAX_TETS:
        raise UserError(f"geometry '{name}': its own mesh sizes (--graded; as small as {lc.min():.3g}) would make "
                        f"~{estimate:.2g} tetrahedra; give coarser sizes in the geometry (its size fields, its points' "
                        f"lengths) for at most {MAX_TETS:.0e}, or mesh it without --graded")


def describe(points, tets):
    edges = np.concatenate([tets[:, [a, b]] for a, b in ((0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3))])
    lengths = np.linalg.norm(points[edges[:, 0]] - points[edges[:, 1]], axis=1)
    return {"vertices": len(points), "tets": len(tets), "min_edge": float(lengths.min()),
            "max_edge": float(lengths.max())}


def cached_bar(level=None, size=None):
    """Path of the cached bar mesh at `level` (or target edge length `size`), generated on first use."""
    name = f"bar_L{level}.msh" if size is None else f"bar_h{size:.4g}.msh"
    path = os.path.join(cache_dir(), name)
    if not os.path.isfile(path):
        generate("bar", level, path, size)
    return path


def size_for_tets(tets):
    """Target edge length giving about `tets` tetrahedra on the bar (from L8's density)."""
    return LEVEL_SIZES[8] * (28210.0 / tets) ** (1.0 / 3.0)
