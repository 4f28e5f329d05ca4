"""`hyperelastic plot`: a PNG of a frame of an output, rendered off-screen by pyvista (VTK) as ParaView would show it:
the body deformed (by its displacement times a scale, automatic where the motion would not show), coloured by any of
its fields (`--field von_mises`, a component `displacement:z`, `stress:xy`), over the reference shape's outline, with
the rigid obstacles of the run drawn (issue 70 item 5); inside the part by a plane (`--slice`, `--clip`); frames as an
animated GIF (`--frames A:B`, assembled by Pillow, matplotlib's dependency). Reads the output file (either layout: its
rows are one mesh); nothing else."""
import math
import os

import numpy as np

from ..core.errors import UserError
from ..core.expressions import TimeFunction
from ..core.files import check_output_path, completed_frames, open_output
from ..physics.effects.contact import split_top
from ..physics.effects.obstacles import parse as parse_obstacle
from .fields import is_point_field

# the direction the camera looks from, and which way is up in the picture
VIEWS = {"iso": None, "x": ((1, 0, 0), (0, 0, 1)), "y": ((0, -1, 0), (0, 0, 1)), "z": ((0, 0, 1), (0, 1, 0))}
TENSOR = ("xx", "xy", "xz", "yy", "yz", "zz")              # (Tensor6, as the output stores it)
PRINCIPAL = ("1", "2", "3")    # a principal field's components: the largest, the middle, the smallest (as stored)
VISIBLE = 0.02        # a displacement below this fraction of the part's size is scaled up to AUTO_SHOW of it
AUTO_SHOW = 0.1


def component(name, spec, values):
    """The scalar per row of field `name` (values: (n,), (n, 3) or (n, 6)) for `spec` (None: its magnitude, or the
    scalar itself; x|y|z of a vector; xx..zz of a tensor; 1|2|3 of principal values, largest first, the largest by
    default: principal_spec); UserError where the field has no such component."""
    v = np.asarray(values, float)
    if v.ndim == 1:
        if spec:
            raise UserError(f"plot: --field {name}:{spec}: '{name}' is a scalar field (no components)")
        return v
    names = PRINCIPAL if name.startswith("principal_") else "xyz" if v.shape[1] == 3 else TENSOR if v.shape[1] == 6 \
        else ()
    spec = principal_spec(name, spec)
    if spec is None:
        return np.linalg.norm(v, axis=1) if v.shape[1] == 3 else v[:, 0]
    if spec not in names:
        raise UserError(f"plot: --field {name}:{spec}: the components of '{name}' are {', '.join(names)}")
    return v[:, names.index(spec)]


def principal_spec(name, spec):
    """The component shown of field `name`: spec, or for principal values without one the largest ('1': a magnitude of
    principal values means nothing)."""
    return "1" if spec is None and name.startswith("principal_") else spec


def _obstacles(attrs, t, lo, hi):
    """[(points, triangles)] of the run's -obstacle items at time t (from its recorded options)."""
    opts = dict(line.split(" ", 1) for line in str(attrs.get("options", "")).splitlines() if " " in line)
    items = [s for s in split_top(opts.get("-obstacle", ""), ";") if s.strip()]
    motions = split_top(opts["-obstacle_motion"], ";") if "-obstacle_motion" in opts else [None] * len(items)
    out = []
    for text, motion in zip(items, motions):
        m = None if motion is None else tuple(TimeFunction(p, "-obstacle_motion") for p in split_top(motion, ","))
        try:
            out.append(parse_obstacle(text, m).drawing(t, lo, hi))
        except UserError:
            continue            # (a triangulated obstacle whose file is not where the run read it: not drawn)
    return out


def _read(path, indices, field):
    """(points X, cells (n, 4), attrs, point field?, [(frame, time, positions x, values)]) of the frames `indices(n)`
    names of an output (n: its frame count; indices raises the line for frames it does not hold), read in one open."""
    name = field.partition(":")[0] if field else "displacement"
    with open_output(path, "plot") as f:
        n = completed_frames(f)
        if n == 0:
            raise UserError(f"plot: '{path}' has no frames")
        X, cells, got = f["mesh/points"][:], f["mesh/tetra"][:, :4], []
        for i in indices(n):
            x, g = f["x"][i], f[f"frames/{i}"]
            if name == "displacement":
                values = x - X
            elif name in g:
                values = g[name][:]
            else:
                raise UserError(f"plot: --field {name}: frame {i} has no such field (it has {', '.join(sorted(g))}; "
                                "-output_fields writes more)")
            got.append((i, float(f["time"][i]), x, values))
        return X, cells, dict(f.attrs), is_point_field(name), got


def _shown(path, X, got, field, scale, cut, which):
    """(title, each frame's scalars, the displacement's scale, each frame's drawn positions, their bounds (lo, hi))
    of the frames `got` (_read's): one scale for all (given, else 1, or larger where the largest motion is under
    VISIBLE of the part's size); one line where a frame's positions are not finite or the cut's plane misses the
    part (`which`: the frames in words)."""
    name, _, spec = (field or "displacement").partition(":")
    scalars = [component(name, spec or None, values) for _, _, _, values in got]
    for i, _, x, _ in got:
        if not (np.isfinite(x).all() and np.isfinite(X).all()):
            raise UserError(f"plot: frame {i} of '{path}' holds non-finite positions (choose others)")
    size = float(np.linalg.norm(X.max(axis=0) - X.min(axis=0))) or 1.0
    moved = max(float(np.linalg.norm(x - X, axis=1).max()) for _, _, x, _ in got)
    if scale is None:
        scale = AUTO_SHOW * size / moved if 0 < moved < VISIBLE * size else 1.0
    shapes = [X + scale * (x - X) for _, _, x, _ in got]
    lo, hi = np.min([x.min(axis=0) for x in shapes], axis=0), np.max([x.max(axis=0) for x in shapes], axis=0)
    if cut is not None and not lo[cut[1]] < cut[2] < hi[cut[1]]:
        raise UserError(f"plot: --{cut[0]} {'xyz'[cut[1]]}={cut[2]:g}: the plane misses the part (its {'xyz'[cut[1]]} "
                        f"from {lo[cut[1]]:.6g} to {hi[cut[1]]:.6g} in {which})")
    spec = principal_spec(name, spec or None)
    return f"{name}{':' + spec if spec else ''}", scalars, scale, shapes, (lo, hi)


def _caption(attrs, t, i, scale, cut):
    """The picture's caption: the scene, the frame's time and number, the displacement's scale, the cut."""
    scaled = "" if scale == 1.0 else f"; displacement x {scale:.3g}"
    return (f"{attrs.get('scene', '')}  t = {t:.6g}  (frame {i}{scaled}"
            f"{'' if cut is None else f'; {cut[0]} {chr(120 + cut[1])} = {cut[2]:g}'})")


def parse_cut(kind, text):
    """(kind, axis 0-2, value) of `--clip|--slice AXIS=VALUE` (a plane x, y or z = VALUE in the drawn configuration);
    None for None; one line for anything else."""
    if text is None:
        return None
    axis, eq, value = text.partition("=")
    try:
        v = float(value)
    except ValueError:
        v = math.nan
    if not eq or axis.strip() not in ("x", "y", "z") or not math.isfinite(v):
        raise UserError(f"plot: --{kind} '{text[:40]}': give AXIS=VALUE, a plane x, y or z = VALUE (e.g. x=0.5)")
    return kind, "xyz".index(axis.strip()), v


def picture(path, out, frame=-1, field=None, view="iso", scale=None, clim=None, cut=None):
    """Render frame `frame` of the output `path` to the PNG `out`; returns the line to print (the field, its range
    and the displacement's scale). cut: parse_cut's (--clip: the part on the lower side of the plane, its inside shown
    on the cut; --slice: the field on the plane alone, with the part's outline). UserError (one line) for what cannot
    be drawn."""
    if not out.lower().endswith(".png") or os.path.isdir(out):
        raise UserError(f"plot: -o '{out}' must be a .png file")
    if view not in VIEWS:
        raise UserError(f"plot: --view {view}: give one of {', '.join(VIEWS)}")

    def one(n):
        i = frame if frame >= 0 else n + frame
        if not 0 <= i < n:
            raise UserError(f"plot: frame {frame} out of range (0..{n - 1})")
        return [i]
    X, cells, attrs, at_points, got = _read(path, one, field)
    (i, t, _, _), = got
    title, (scalars,), scale, (xs,), _ = _shown(path, X, got, field, scale, cut, f"frame {i}")
    check_output_path(out, [path], suffixes=())
    _draw(out, X, xs, cells, scalars, at_points, title, view, clim, cut,
          _obstacles(attrs, t, X.min(axis=0), X.max(axis=0)) if scale == 1.0 else [], _caption(attrs, t, i, scale, cut))
    lo, hi = (clim if clim is not None else (float(np.nanmin(scalars)), float(np.nanmax(scalars))))
    return f"wrote {out} (field {title} from {lo:.6g} to {hi:.6g}, displacement scale {scale:.3g})"


FRAME_SECONDS = 0.1          # an animation's frame on screen


def animation(path, out, frames, field=None, view="iso", scale=None, clim=None, cut=None):
    """Frames a..b (frames = (a, b), both included) of the output `path` as an animated GIF or an MP4 video (H.264,
    by the ffmpeg that the imageio-ffmpeg wheel carries) `out`, one camera, one colour range (--range, else the
    frames' least and largest) and one displacement scale (as picture's, from the frames' largest motion) for all;
    returns the line to print. UserError (one line) for what cannot be drawn."""
    if not out.lower().endswith((".gif", ".mp4")) or os.path.isdir(out):
        raise UserError(f"plot: -o '{out}' must be a .gif or .mp4 file with --frames")
    if view not in VIEWS:
        raise UserError(f"plot: --view {view}: give one of {', '.join(VIEWS)}")
    a, b = frames

    def span(n):
        if b >= n:
            raise UserError(f"plot: --frames {a}:{b}: '{path}' holds frames 0..{n - 1}")
        return range(a, b + 1)
    X, cells, attrs, at_points, got = _read(path, span, field)
    title, values, scale, shapes, (lo, hi) = _shown(path, X, got, field, scale, cut, f"frames {a}..{b}")
    check_output_path(out, [path], suffixes=())
    if clim is None:
        clim = [float(min(np.nanmin(v) for v in values)), float(max(np.nanmax(v) for v in values))]
        clim = clim if clim[0] < clim[1] else [clim[0] - 0.5, clim[0] + 0.5]
    import tempfile
    from PIL import Image
    with tempfile.TemporaryDirectory() as d:
        pngs = []
        for k, ((i, t, _, _), xs, v) in enumerate(zip(got, shapes, values)):
            pngs.append(os.path.join(d, f"{k:06d}.png"))
            _draw(pngs[-1], X, xs, cells, v, at_points, title, view, clim, cut,
                  _obstacles(attrs, t, X.min(axis=0), X.max(axis=0)) if scale == 1.0 else [],
                  _caption(attrs, t, i, scale, cut), bounds=[lo[0], hi[0], lo[1], hi[1], lo[2], hi[2]])
        images = [Image.open(p).convert("RGB") for p in pngs]
        video = out.lower().endswith(".mp4")
        tmp = f"{out}.{os.getpid()}.tmp" + (".mp4" if video else ".gif")
        try:
            if video:
                _write_mp4(tmp, images)
            else:
                images[0].save(tmp, save_all=True, append_images=images[1:], duration=int(1000 * FRAME_SECONDS),
                               loop=0)
            os.replace(tmp, out)
        except OSError as e:
            raise UserError(f"plot: cannot write '{out}' ({e.strerror or e})") from None
        finally:
            if os.path.exists(tmp):
                os.remove(tmp)
    return (f"wrote {out} ({len(got)} frames {a}..{b}, field {title} from {clim[0]:.6g} to {clim[1]:.6g}, "
            f"displacement scale {scale:.3g})")


def _write_mp4(path, images):
    """The RGB images as an H.264 video at 1/FRAME_SECONDS frames a second (yuv420p, what players take: even sizes, the
    images padded by a row or column where odd), through the ffmpeg of the imageio-ffmpeg wheel."""
    import imageio_ffmpeg        # deferred on purpose: only a video needs it
    w, h = images[0].size
    W, H = w + w % 2, h + h % 2
    gen = imageio_ffmpeg.write_frames(path, (W, H), fps=1 / FRAME_SECONDS, codec="libx264", macro_block_size=2,
                                      ffmpeg_log_level="error")
    gen.send(None)
    for im in images:
        a = np.zeros((H, W, 3), np.uint8)
        a[:h, :w] = np.asarray(im, np.uint8)
        gen.send(a.tobytes())
    gen.close()


def _draw(out, X, xs, cells, scalars, at_points, title, view, clim, cut, obstacles, caption, bounds=None):
    import pyvista as pv      # deferred on purpose: VTK takes ~1 s to load, and only pictures need it
    import vtk
    vtk.vtkLogger.SetStderrVerbosity(vtk.vtkLogger.VERBOSITY_OFF)   # (an X server's absence is no news off-screen)
    pv.OFF_SCREEN = True
    kinds = np.full(len(cells), pv.CellType.TETRA, np.uint8)
    flat = np.hstack([np.full((len(cells), 1), 4), cells]).ravel()
    body = pv.UnstructuredGrid(flat, kinds, xs)
    (body.point_data if at_points else body.cell_data)[title] = scalars
    ref = pv.UnstructuredGrid(flat, kinds, X).extract_surface(algorithm="dataset_surface").extract_feature_edges(30)
    p = pv.Plotter(off_screen=True, window_size=(1000, 700))
    shown = body.extract_surface(algorithm="dataset_surface")
    if cut is not None:
        normal, origin = np.eye(3)[cut[1]], np.eye(3)[cut[1]] * cut[2]
        shown = (body.clip(normal=normal, origin=origin, invert=True).extract_surface(algorithm="dataset_surface")
                 if cut[0] == "clip" else body.slice(normal=normal, origin=origin))
    p.add_mesh(shown, scalars=title, cmap="viridis", clim=clim, scalar_bar_args={"title": title, "vertical": False})
    p.add_mesh(ref, color="grey", opacity=0.5, line_width=1)
    for pts, tris in obstacles:
        faces = np.hstack([np.full((len(tris), 1), 3), tris]).ravel()
        p.add_mesh(pv.PolyData(np.asarray(pts, float), faces), color="lightgrey", opacity=0.35)
    p.add_text(caption, font_size=10)
    if VIEWS[view] is None:
        p.view_isometric()
    else:
        p.view_vector(VIEWS[view][0], viewup=VIEWS[view][1])
    if bounds is not None:        # (an animation's frames: one camera for all)
        p.reset_camera(bounds=bounds)
    tmp = f"{out}.{os.getpid()}.tmp.png"
    try:
        p.screenshot(tmp)
        os.replace(tmp, out)
    except OSError as e:
        raise UserError(f"plot: cannot write '{out}' ({e.strerror})") from None
    finally:
        p.close()
        if os.path.exists(tmp):
            os.remove(tmp)
