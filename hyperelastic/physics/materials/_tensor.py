import numpy as np

I3 = np.eye(3)


def sym(A):
    return 0.5 * (A + np.swapaxes(A, -1, -2))


def tr(A):
    return np.trace(A, axis1=-2, axis2=-1)


def T(A):
    return np.swapaxes(A, -1, -2)
