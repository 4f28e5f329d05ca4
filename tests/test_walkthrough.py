"""The README's rubber walkthrough ('A rubber part: Rivlin's torsion') runs as written, from a scratch directory with
the project's .venv and examples/, and its answer is what the README says: the torque within 0.1% of Rivlin's closed
form M = (pi/2) mu (psi/L) a^4 for an incompressible neo-Hookean cylinder (issue 47)."""
import math
import os
import re
import subprocess

from conftest import ROOT


def walkthrough_commands():
    text = open(os.path.join(ROOT, "README.md"), encoding="utf-8").read()
    section = text.split("## A rubber part: Rivlin's torsion", 1)[1].split("\n## ", 1)[0]
    return [ln.strip() for ln in section.splitlines() if ln.startswith("    .venv/")]


def test_rubber_walkthrough_runs_and_meets_rivlin(tmp_path):
    cmds = walkthrough_commands()
    assert len(cmds) == 3
    for name in (".venv", "examples"):
        os.symlink(os.path.join(ROOT, name), tmp_path / name)
    (tmp_path / "output").mkdir()
    for cmd in cmds:
        p = subprocess.run(cmd, shell=True, cwd=tmp_path, capture_output=True, text=True, timeout=600,
                           stdin=subprocess.DEVNULL)
        assert p.returncode == 0, f"{cmd}\n{p.stderr[-2000:]}"
    m = re.search(r"moment_z:top:0,0,0\.04 = (\S+)", p.stdout)
    assert m, p.stdout
    mu, a, L, psi = 5e5, 0.01, 0.04, math.pi / 2
    rivlin = math.pi / 2 * mu * (psi / L) * a ** 4
    assert abs(float(m.group(1)) / rivlin - 1) < 1e-3, (m.group(1), rivlin)
