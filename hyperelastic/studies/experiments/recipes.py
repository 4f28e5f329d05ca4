"""Jacobian modes and solver recipes, for the experiments.

MODES: the options that select each Jacobian mode, nothing else (KSP and PC keep the application's
defaults). Solver recipes are the files options/NAME.opts (also usable as `-options_file`); a recipe
splits into its PC part (the options of the preconditioner: -pc_*, -sub_pc_*, -mg_*) and the rest, so
that a study can combine a mode's recipe with another recipe's preconditioner.
"""
import os

from ...core.data import OPTIONS_DIR
from ...core.options import parse_options_file

MODES = {"assembled": ["-jacobian", "assembled"], "shell": ["-jacobian", "shell"], "snes_mf": ["-snes_mf"],
         "snes_mf_operator": ["-snes_mf_operator", "-jacobian", "assembled"], "seed_fd": ["-jacobian", "seed_fd"],
         "seed_fd2": ["-jacobian", "seed_fd2"]}
PC_PREFIXES = ("pc_", "sub_pc_", "mg_")


def recipe(name):
    """[(key, value or None)] of options/NAME.opts."""
    return parse_options_file(os.path.join(OPTIONS_DIR, f"{name}.opts"))


def args(pairs):
    """Command-line arguments of (key, value) pairs."""
    out = []
    for k, v in pairs:
        out += [f"-{k}"] + ([v] if v is not None else [])
    return out


def without_pc(name):
    """The arguments of recipe NAME without its preconditioner options."""
    return args((k, v) for k, v in recipe(name) if not k.startswith(PC_PREFIXES))


def pc_of(name):
    """The preconditioner options of recipe NAME."""
    return args((k, v) for k, v in recipe(name) if k.startswith(PC_PREFIXES))
