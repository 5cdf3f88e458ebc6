"""photogram.geometry.aiming.look_at: cameras aimed at a target."""

import numpy as np

from photogram.geometry.aiming import look_at


def test_look_at_aims_the_minus_z_axis_at_the_target_with_up_up():
    X0 = np.array([[10.0, -5.0, 3.0], [-2.0, 7.0, 1.0], [0.0, 0.0, 20.0]])
    target = np.array([1.0, 2.0, 0.5])
    R = look_at(X0, target)
    assert R.shape == (3, 3, 3)
    for Ri, x0 in zip(R, X0):
        assert np.allclose(Ri @ Ri.T, np.eye(3), atol=1e-12)
        assert np.isclose(np.linalg.det(Ri), 1.0)
        Xc = Ri @ (target - x0)                 # the target in the camera frame
        assert np.allclose(Xc[:2], 0.0, atol=1e-9) and Xc[2] < 0   # on the -z axis
        assert abs(Ri[0, 2]) < 1e-12            # camera x horizontal (no roll)
        assert Ri[1] @ [0.0, 0.0, 1.0] > 0      # world up is up in the image (camera y)


def test_look_at_single_camera_and_other_up():
    R = look_at([0.0, 0.0, 0.0], [0.0, 5.0, 0.0], up=(1.0, 0.0, 0.0))
    assert R.shape == (1, 3, 3)
    assert np.allclose(R[0] @ [0.0, 5.0, 0.0], [0.0, 0.0, -5.0])
    assert np.allclose(R[0, 1], [1.0, 0.0, 0.0])      # camera y along the given up


def test_simulation_network_uses_the_same_function():
    from photogram.simulation import network
    assert network.look_at is look_at
