"""A check shared by the mocap tests: the gradient of a joint batch's
energy (poses ``a`` and camera rotation coefficients ``g``) against central
differences."""

import numpy as np


def assert_gradient_is_minus_twice_rhs(jb, a, g, args, picks):
    """``linearize`` of the batch ``jb`` gives E, H and rhs with the
    gradient of E equal to ``-2 rhs``; checked by central differences on
    the coordinates ``picks`` of (a, g) flattened, and H symmetric."""
    E, H, rhs = jb.linearize(a, g, *args, second_order=False)
    assert np.isclose(E[0], jb.energy(a, g, *args)[0], rtol=1e-12)
    x = np.concatenate([a.ravel(), g.ravel()])
    nP = a.size
    for i in picks:
        h = 1e-6 * max(1.0, abs(x[i]))
        xp, xm = x.copy(), x.copy()
        xp[i] += h
        xm[i] -= h
        ep = jb.energy(xp[:nP].reshape(a.shape), xp[nP:].reshape(g.shape), *args)[0]
        em = jb.energy(xm[:nP].reshape(a.shape), xm[nP:].reshape(g.shape), *args)[0]
        fd = (ep - em) / (2 * h)
        assert abs(fd + 2 * rhs[0, i]) < 1e-5 * max(1.0, abs(fd)) + 1e-6 * abs(E[0])
    assert np.allclose(H[0], H[0].T)
