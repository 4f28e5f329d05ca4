"""The rubber walkthrough's rod (docs/guide/rubber.md, whose commands tests/test_docs.py runs as written) priced by
`study price`: the torque within its estimated error of Rivlin's closed form M = (pi/2) mu (psi/L) a^4 for an
incompressible neo-Hookean cylinder (issue 47)."""
import math
import os
import re
import subprocess

from conftest import ROOT


def test_price_of_the_torque_answers_and_is_true(tmp_path):
    """`study price --watch moment_z:top:0,0,0.04 --target 0.01` on the walkthrough's rod (issue 47: the studies
    never answered): P1 is left after its first run (it locks), the solver tolerances are probed on P2, and within
    --max-runs 4 the report names the cheapest P2 run whose estimate meets the target (unconfirmed: a third level
    is over the limit); its torque is within the estimated error (x2) of Rivlin's closed form."""
    out = tmp_path / "p"
    p = subprocess.run([os.path.join(ROOT, ".venv", "bin", "hyperelastic"), "study", "price", "--part",
                        f"{ROOT}/examples/rod.geo", "--scene", f"{ROOT}/examples/torsion.opts", "--size", "0.005",
                        "--watch", "moment_z:top:0,0,0.04", "--target", "0.01", "--max-runs", "4", "-output_dir",
                        str(out)], capture_output=True, text=True, timeout=600)
    assert p.returncode == 0, p.stderr[-2000:]
    first = open(out / "price.md").read().split("\n\n")[1]
    m = re.search(r"the cheapest run whose estimate meets it is (P\d) r(\d).*?= (\S+), estimated error (\S+) "
                  r"\(unconfirmed\)", first)
    assert m and m.group(1) == "P2" and "Order 1 was left: linear tetrahedra lock" in first, first
    q, est = float(m.group(3).rstrip(",")), float(m.group(4))
    rivlin = math.pi / 2 * 5e5 * (math.pi / 2 / 0.04) * 0.01 ** 4
    assert est <= 0.01 and abs(q / rivlin - 1) <= 2 * est, (q, est, rivlin)
