"""Patch test and rigid-motion invariance on the L1 bar, through the compiled kernels."""
import numpy as np
import pytest

from hyperelastic.discretization.kernels import CellKernels
from hyperelastic.physics.materials import MATERIALS, default_solid
from hyperelastic.mesh.read import read


@pytest.fixture(scope="module")
def bar(l1_mesh):
    X, tets = read(l1_mesh)
    D = np.stack([X[tets[:, a]] - X[tets[:, 0]] for a in (1, 2, 3)], axis=-1)
    lo, hi = X.min(0), X.max(0)
    interior = ~((np.abs(X - lo) < 1e-9) | (np.abs(X - hi) < 1e-9)).any(axis=1)
    assert interior.sum() > 10
    return X, tets, np.linalg.inv(D), np.abs(np.linalg.det(D)) / 6, interior


def forces(bar, name, x):
    X, tets, Dminv, vol, _ = bar
    k = CellKernels(tets, Dminv, vol, default_solid(name).material, default_solid(name).constants)
    f = np.zeros(x.size)
    k.forces(np.ascontiguousarray(x.ravel()), f)
    return f.reshape(-1, 3)


@pytest.mark.parametrize("name", sorted(MATERIALS))
def test_patch_affine_deformation_gives_zero_interior_force(bar, name):
    X, _, _, _, interior = bar
    A = np.eye(3) + 0.1 * np.random.default_rng(7).standard_normal((3, 3))
    f = forces(bar, name, X @ A.T + np.array([0.3, -0.2, 0.1]))
    scale = np.abs(f).max()
    assert scale > 1e3                      # a real deformation: boundary forces are large
    assert np.abs(f[interior]).max() <= 1e-10 * scale


def rotation(axis, angle):
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle) * K + (1 - np.cos(angle)) * K @ K


@pytest.mark.parametrize("name", ["stvk", "neohookean", "neohookean_split", "mooney_rivlin"])
def test_rigid_rotation_gives_zero_force(bar, name):
    X = bar[0]
    R = rotation([1, 2, 3], 1.1)
    f = forces(bar, name, X @ R.T + 2.0)
    ref = np.abs(forces(bar, name, X * 1.01)).max()   # 1% stretch, for scale
    assert np.abs(f).max() <= 1e-10 * ref


def test_linear_material_has_rotation_artifacts(bar):
    """Linear elasticity is not rotation invariant (thesis sec. 3.4.1): a rigid rotation gives forces."""
    X = bar[0]
    f = forces(bar, "linear", X @ rotation([0, 0, 1], 0.5).T)
    ref = np.abs(forces(bar, "linear", X * 1.01)).max()
    assert np.abs(f).max() > 1.0 * ref
