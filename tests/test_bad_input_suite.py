"""The generated bad-input suite (tests/bad_input_suite.py): its quick subset, one test per case, and
the suite's own shape. The whole suite: `.venv/bin/python tests/bad_input_suite.py` (about 3 minutes)."""
from collections import Counter

import pytest

import bad_input_suite as suite

CASES = suite.all_cases()
QUICK = CASES[::suite.QUICK_EVERY]


@pytest.fixture(scope="module")
def world(tmp_path_factory):
    return suite.make_world(str(tmp_path_factory.mktemp("badinput") / "world"))


def test_the_suite_covers_the_issue():
    """At least 600 distinct cases from the seed, ~60 under 2 ranks, every kind of bad input the issue
    names; the same seed gives the same cases."""
    names = [c.name for c in CASES]
    assert len(set(names)) == len(names) >= 600
    assert 55 <= sum(c.name.startswith("mpi2:") for c in CASES) <= 70
    cats = Counter(c.category for c in CASES)
    for cat in ("option values", "PETSc values", "unknown options", "conflicting combinations",
                "scene and options files", "meshes", "output paths", "restart files", "plot"):
        assert cats[cat] >= 7, (cat, cats[cat])
    kinds = " ".join(names)
    for kind in ("truncated", "nan@", "huge@", "duplicate_tet", "overlapping_tet", "inverted@", "only_triangle",
                 "index_out_of_range", "=''", "='nan'", "='inf'", "='1e308'", "='abc'", "='1,2'", "typo:",
                 "scene:empty", "scene:binary", "scene:latin1", "options_file:self", "scene:fifo", "mesh:fifo",
                 "output:directory", "output:dev_full", "output:too_long", "output:equals_mesh", "disk_full",
                 "restart:truncated", "restart:other_mesh", "restart:x_wrong_shape", "restart:h_nan"):
        assert kind in kinds, kind
    assert [c.name for c in suite.all_cases()] == names


CONTRACTS = [c for c in CASES if c.category == "contracts"]


@pytest.mark.parametrize("case", QUICK + [c for c in CONTRACTS if c not in QUICK],
                         ids=[c.name for c in QUICK] + [c.name for c in CONTRACTS if c not in QUICK])
def test_bad_input_case(case, world, tmp_path):
    outcome, detail = suite.run_case(case, world, str(tmp_path))
    assert outcome == "pass", f"{outcome}: {detail}"
