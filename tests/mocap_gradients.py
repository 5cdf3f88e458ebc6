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


def assert_rotation_jacobians(R_ref, g, noisy, J0, J1, h=1e-6):
    """The Jacobians ``J0``, ``J1`` of the rotation residuals (E_rot, eq.
    (14)) of frames t, t+1 with respect to the Euler angles ``g`` (T, 3) of
    frame t, against central differences."""
    from photogram.mocap.motion.camera_motion import euler_matrices, rotation_residuals
    T = g.shape[0]
    for t in range(T):
        for a in range(3):
            gp, gm = g.copy(), g.copy()
            gp[t, a] += h
            gm[t, a] -= h
            fd = (rotation_residuals(R_ref, euler_matrices(gp), None, noisy, False)
                  - rotation_residuals(R_ref, euler_matrices(gm), None, noisy, False)) / (2 * h)
            an = np.zeros_like(fd)
            if t < T - 1:
                an[t] += J0[t, :, a]
            if t > 0:
                an[t - 1] += J1[t - 1, :, a]
            assert np.max(np.abs(fd - an)) < 1e-6 * max(1.0, np.max(np.abs(an)))
