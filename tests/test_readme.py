"""The README's commands run as written (issue 15): the lines of its 'Running' section, in order, from
a scratch directory that has the project's .venv and examples/ (nothing else is prepared)."""
import os
import re
import subprocess

from conftest import ROOT


def running_commands():
    text = open(os.path.join(ROOT, "README.md"), encoding="utf-8").read()
    section = text.split("## Running", 1)[1].split("\n\n(", 1)[0]
    return [re.sub(r"\s+#.*$", "", ln.strip()) for ln in section.splitlines() if ln.startswith("    .venv/")]


def test_running_section_runs_as_written(tmp_path):
    cmds = running_commands()
    assert len(cmds) >= 8 and any("mpiexec" in c for c in cmds)
    for name in (".venv", "examples"):       # (the recipes are found by name: options/gamg.opts from anywhere)
        os.symlink(os.path.join(ROOT, name), tmp_path / name)
    for cmd in cmds:
        p = subprocess.run(cmd, shell=True, cwd=tmp_path, capture_output=True, text=True, timeout=300,
                           stdin=subprocess.DEVNULL)
        assert p.returncode == 0, f"{cmd}\n{p.stderr[-2000:]}"
    for f in ("output/bend.h5", "output/twist3.h5", "output/bar8.msh", "output/bracket.h5", "output/bend.png"):
        assert (tmp_path / f).stat().st_size > 0, f
