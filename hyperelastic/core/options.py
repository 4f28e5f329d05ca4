"""Typed, validated access to the PETSc options database, and scene files.

A scene file is a PETSc options file (one `-key value` or `-flag` per line, `#` comments). Its
values are defaults: an option given on the command line wins.
"""
import math
import os
import re
import sys
from dataclasses import dataclass

from petsc4py import PETSc

from .errors import UserError
from .expressions import TimeFunction
from .data import SCENES_DIR, builtin_scenes
from .files import option_lines



@dataclass(frozen=True)
class Row:
    """Options as `-help` and the options reference list them: one row of related options. The catalog
    (catalog.py) gathers the rows of the application, of every material and of every effect."""
    names: tuple      # the options of the row, without the dash (REGION_x / LOAD_x: per region / load)
    synopsis: str     # how the row shows them (the options reference's first column)
    help: str         # what they do (backticks: code)
    default: str = ""


MAX_MAGNITUDE = 1e30    # bound on any real an option gives (the products the kernels form stay finite)


def parse_options_file(path):
    """[(key, value-or-None)] from a PETSc options file; UserError on a malformed line, a file that is not
    UTF-8 text, or one that holds no options."""
    try:
        with open(path, "rb") as fh:
            data = fh.read()
    except OSError as e:
        raise UserError(f"scene '{path}': cannot be read ({e.strerror})") from None
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise UserError(f"scene '{path}': not UTF-8 text (byte {e.start})") from None
    if "\0" in text:
        raise UserError(f"scene '{path}': holds NUL bytes (not a text file)")
    pairs = []
    for lineno, key, value in option_lines(text, f"scene '{path}'"):
        if key == "options_file":
            raise UserError(f"scene '{path}' line {lineno}: a scene cannot include options files (give "
                            "-options_file on the command line)")
        pairs.append((key, value))
    if not pairs:
        raise UserError(f"scene '{path}': holds no options (a scene names at least its mesh, material or effects)")
    return pairs


def resolve_scene(scene):
    """Path of a scene: a built-in name (options/scenes/NAME.opts) or a path to an options file."""
    if os.path.isfile(scene):
        return scene
    if os.path.exists(scene):
        raise UserError(f"scene '{scene}': is not a regular file")
    path = os.path.join(SCENES_DIR, f"{scene}.opts")
    if os.path.isfile(path):
        return path
    raise UserError(f"unknown scene '{scene}' (built-in: {', '.join(builtin_scenes())}; or a path to an "
                    "options file)")


def insert_defaults(pairs, opts=None):
    """Insert (key, value) pairs into the options database unless already set (command line wins)."""
    opts = opts or PETSc.Options()
    for key, val in pairs:
        if not opts.hasName(key):
            opts.setValue(key, "" if val is None else val)


class Options:
    """Reads options with a clear one-line error for a wrong value."""

    def __init__(self, prefix=None):
        self.o = PETSc.Options(prefix)

    def has(self, name):
        return self.o.hasName(name)

    def string(self, name, default=None):
        v = self.o.getString(name, default) if self.o.hasName(name) else default
        if self.o.hasName(name) and (v is None or v == ""):
            raise UserError(f"option -{name}: needs a value")
        return v

    def real(self, name, default=None, minimum=None, exclusive=True, maximum=None):
        s = self.string(name, None)
        if s is None:
            return default
        try:
            v = float(s)
        except ValueError:
            raise UserError(f"option -{name}: '{s}' is not a number") from None
        if not math.isfinite(v):
            raise UserError(f"option -{name}: {s} is not a finite number")
        if abs(v) > MAX_MAGNITUDE:
            raise UserError(f"option -{name}: {s} is beyond {MAX_MAGNITUDE:g} in magnitude (no physical value in "
                            "SI units is)")
        if v != 0 and abs(v) < sys.float_info.min:
            raise UserError(f"option -{name}: {s} is below the smallest normal number ({sys.float_info.min:.3g})")
        if minimum is not None and (v <= minimum if exclusive else v < minimum):
            raise UserError(f"option -{name}: {s} must be {'>' if exclusive else '>='} {minimum:g}")
        if maximum is not None and v > maximum:
            raise UserError(f"option -{name}: {s} must be <= {maximum:g}")
        return v

    def integer(self, name, default=None, minimum=None):
        s = self.string(name, None)
        if s is None:
            return default
        try:
            v = int(s)
        except ValueError:
            raise UserError(f"option -{name}: '{s}' is not an integer") from None
        if minimum is not None and v < minimum:
            raise UserError(f"option -{name}: {v} must be >= {minimum}")
        return v

    def flag(self, name, default=False):
        if not self.o.hasName(name):
            return default
        s = (self.o.getString(name, "") or "").lower()
        if s in ("", "1", "true", "yes", "on"):
            return True
        if s in ("0", "false", "no", "off"):
            return False
        raise UserError(f"option -{name}: '{s}' is not a boolean")

    def choice(self, name, choices, default):
        v = self.string(name, default)
        if v not in choices:
            raise UserError(f"option -{name}: unknown value '{v}' (choose from {', '.join(choices)})")
        return v

    def vector(self, name, n=3):
        s = self.string(name, None)
        if s is None:
            return None
        parts = s.replace(";", ",").split(",")
        try:
            vals = [float(p) for p in parts]
        except ValueError:
            raise UserError(f"option -{name}: '{s}' is not a list of {n} numbers (e.g. 0,0,-9.81)") from None
        if len(vals) != n or not all(math.isfinite(v) for v in vals):
            raise UserError(f"option -{name}: '{s}' is not a list of {n} finite numbers (e.g. 0,0,-9.81)")
        if max(abs(v) for v in vals) > MAX_MAGNITUDE:
            raise UserError(f"option -{name}: '{s}' has a value beyond {MAX_MAGNITUDE:g} in magnitude")
        return vals

    def numbers(self, name, most, example):
        """A list of 1 to `most` finite numbers, comma-separated (-prony_tau 0.2,1, -ogden_mu 0.63e6,1.2e3), as a
        tuple; None where the option is not given."""
        text = self.string(name, None)
        if text is None:
            return None
        try:
            vals = [float(w) for w in text.split(",")]
        except ValueError:
            raise UserError(f"option -{name}: '{text[:60]}' is not a list of numbers (e.g. {example})") from None
        if not vals or len(vals) > most or not all(math.isfinite(v) for v in vals):
            raise UserError(f"option -{name}: '{text[:60]}' must be 1 to {most} finite numbers")
        return tuple(vals)

    def names(self, name, default=""):
        s = self.string(name, default)
        if not s:
            return []
        words = [w.strip() for w in s.split(",")]
        if not all(words):
            raise UserError(f"option -{name}: '{s}' has an empty entry (a comma-separated list of names)")
        return words


def all_options():
    """The whole options database as a sorted list of (key, value), each value whole. (petsc4py's getAll splits
    PETSc's one-line listing at spaces: `-prescribe_x "X*cos(a) - Y*sin(a)"` came back as `X*cos(a)`, and a restart
    replayed the cut expression. PETSc's own view lists one option a line.)"""
    import tempfile
    opts = PETSc.Options()
    with tempfile.TemporaryDirectory() as d:
        path = os.path.join(d, "options.txt")
        viewer = PETSc.Viewer().createASCII(path, comm=PETSc.COMM_SELF)
        opts.view(viewer)
        viewer.destroy()
        with open(path, encoding="utf-8", errors="replace") as fh:
            lines = fh.read().splitlines()
    out = {}
    for line in lines:
        if not line.startswith("-"):
            continue                          # (the table's first and last lines are comments)
        text = re.sub(r" # \(source: [^)]*\)$", "", line)
        key, _, value = text[1:].partition(" ")
        out[key] = value
    return sorted(out.items())


PREFIX = re.compile(r"[A-Za-z0-9_]+")     # what a region's or load's name must be to prefix options


def option_prefix(name, option):
    """UserError unless `name` (listed in -`option`) can prefix options."""
    if not PREFIX.fullmatch(name):
        raise UserError(f"option -{option}: '{name}' cannot be an option prefix (letters, digits and _ only; a "
                        "physical group can also be named by its tag)")


def prefixed_names(opts, option):
    """The names -`option` lists, each checked as an option prefix and listed once."""
    out = []
    for name in opts.names(option):
        option_prefix(name, option)
        if name in out:
            raise UserError(f"option -{option}: '{name}' is listed twice")
        out.append(name)
    return out


def facet_sets(opts, name, default=None, components=False):
    """The facet sets an option names: a comma list of physical surface names or tags, or bounding-box
    faces (left, right, front, back, bottom, top); resolved against the mesh when it is read. With
    `components`, each may end in :x, :yz, ... (the components it holds; default all three). Returns
    [(name, components)]."""
    items = opts.names(name, default or "")
    if not items:
        raise UserError(f"option -{name}: needs a list of surfaces (physical names or tags, left, right, "
                        "front, back, bottom, top, or x=V, box=..., normal=...)")
    out = []
    for it in items:
        set_name, sep, comps = it.partition(":")
        if not set_name:
            raise UserError(f"option -{name}: '{it}' names no surface")
        if sep and not components:
            raise UserError(f"option -{name}: '{it}': components (:{comps}) are not taken here")
        if sep and (not comps or set(comps) - set("xyz") or len(set(comps)) != len(comps)):
            raise UserError(f"option -{name}: '{it}': components must be some of x, y, z once each (e.g. "
                            f"{set_name}:x or {set_name}:xz)")
        out.append((set_name, comps if sep else "xyz"))
    return out


def volume_sets(opts, name):
    """The physical volumes (names or tags) an option lists; [] when it is not given (the whole body)."""
    if opts.has(name) and not opts.names(name):
        raise UserError(f"option -{name}: needs a list of physical volumes (names or tags)")
    return opts.names(name)


def time_function(opts, prefix):
    """A load's time function: -PREFIX_time EXPR (an expression of t), or -PREFIX_ramp A (A min(t,1));
    None (factor 1) without either."""
    if opts.has(f"{prefix}_time") and opts.has(f"{prefix}_ramp"):
        raise UserError(f"options -{prefix}_time and -{prefix}_ramp: give one time function, not both")
    if opts.has(f"{prefix}_time"):
        return TimeFunction(opts.string(f"{prefix}_time"), f"option -{prefix}_time")
    return opts.real(f"{prefix}_ramp", None)


def needs(where, effect, what):
    """The UserError of an effect switched on without the options it cannot do without."""
    return UserError(f"{where}: effect '{effect}' needs {what}")
