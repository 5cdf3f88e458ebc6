"""The shortcuts of the synthetic renderers (issue 23, item 6: test budget)
against the direct computations they replace: the board renderer's hit test
and block means, the jump renderer's one projection per frame and its
masked slope texture. The rendered images themselves are compared before
and after in docs/benchmarks.md (the test suite, renderers)."""

import numpy as np
import pytest

pytest.importorskip("cv2")

from photogram.simulation.board_rig import render as rig_render          # noqa: E402
from photogram.simulation.board_rig.geometry import _rotvec              # noqa: E402
from photogram.simulation.jump_video import render as jv_render          # noqa: E402
from photogram.simulation.jump_video import scene                        # noqa: E402
from photogram.simulation.jump_video.actors import JumperMotion          # noqa: E402
from photogram.simulation.jump_video.settings import STATIONS, harsh_settings  # noqa: E402


def _hit_direct(xn, R_cb, t_cb, margin, W, H):
    """The ray-plane intersection with d = (x, y, 1) as a (..., 3) array."""
    d = np.concatenate([xn, np.ones(xn.shape[:-1] + (1,))], -1)
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = (R_cb[:, 2] @ t_cb) / (d @ R_cb[:, 2])
        bx = lam * (d @ R_cb[:, 0]) - R_cb[:, 0] @ t_cb + margin
        by = lam * (d @ R_cb[:, 1]) - R_cb[:, 1] @ t_cb + margin
    inside = (lam > 0) & (bx >= 0) & (bx <= W) & (by >= 0) & (by <= H)
    return bx, by, inside


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_board_hit_equals_the_direct_intersection(seed):
    rng = np.random.default_rng(seed)
    xn = rng.uniform(-0.6, 0.6, (50, 60, 2))
    R_cb = _rotvec(rng.normal(0, 0.6, 3))
    t_cb = np.array([-0.3, -0.2, 2.5]) + rng.normal(0, 0.1, 3)
    bx, by, inside = rig_render._hit(xn, R_cb, t_cb, 0.02, 0.6, 0.44)
    bx0, by0, inside0 = _hit_direct(xn, R_cb, t_cb, 0.02, 0.6, 0.44)
    assert 0 < inside0.sum() < inside0.size                # some rays hit, some miss
    np.testing.assert_allclose(bx, bx0, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(by, by0, rtol=1e-12, atol=1e-12)
    # a ray exactly on the paper's edge may flip; none lies that close here
    assert np.array_equal(inside, inside0)
    # the (x, y) pair form gives the same bits as the array form
    pair = rig_render._hit((xn[..., 0].copy(), xn[..., 1].copy()), R_cb, t_cb, 0.02, 0.6, 0.44)
    assert all(np.array_equal(a, b, equal_nan=True) for a, b in zip(pair, (bx, by, inside)))


@pytest.mark.parametrize("s", [1, 2, 3])
def test_box_mean_is_the_block_mean(s):
    a = np.random.default_rng(s).uniform(0, 255, (7 * s, 11 * s)).astype(np.float32)
    expected = a.astype(np.float64).reshape(7, s, 11, s).mean((1, 3))
    np.testing.assert_allclose(rig_render._box_mean(a, s), expected, rtol=1e-12)


def test_one_projection_per_frame_equals_one_per_part_list():
    settings = harsh_settings()            # with bystanders: several groups
    motion = JumperMotion()
    camera = jv_render.drawing_camera(jv_render._cameras()[STATIONS[0]])
    frame = settings.lead_in + 5 - settings.offset(STATIONS[0])
    groups = jv_render._groups(STATIONS[0], frame, settings, motion)
    assert len(groups) >= 2 and all(len(p) == settings.subframes for p, _ in groups)
    together = jv_render._project_all(groups, camera)
    for (parts_list, grey), projs in zip(groups, together):
        for parts, (shapes, discs, depth) in zip(parts_list, projs):
            shapes0, discs0, depth0 = jv_render._project_parts(parts, camera, grey)
            assert depth == depth0 and len(shapes) == len(shapes0) and len(discs) == len(discs0)
            for a, b in zip(shapes, shapes0):
                np.testing.assert_allclose(a.outline, b.outline, rtol=0, atol=1e-9)
            for a, b in zip(discs, discs0):
                np.testing.assert_allclose(a.centre, b.centre, rtol=0, atol=1e-9)
                assert a.radius == b.radius


def _slope_grey_everywhere(X, Y, t):
    """Every texture evaluated at every point, then selected."""
    vn = scene._value_noise
    g = 212.0 + 7.0 * vn(X, Y, 90.0, t[0]) + 3.5 * vn(X, Y, 9.0, t[1]) + 2.5 * vn(X, Y, 1.6, t[2])
    prepared = np.abs(Y) <= scene.SLOPE_HALF_WIDTH
    g += np.where(prepared, 1.5 * np.sin(2 * np.pi * Y / 2.5), 0.0)
    line = prepared & (np.abs(((X - 400.0) + 25.0) % 50.0 - 25.0) < 0.6)
    g -= np.where(line, 18.0, 0.0)
    g += np.where(~prepared, -6.0 + 6.0 * vn(X, Y, 4.0, t[3]), 0.0)
    return np.where(np.abs(Y) > scene.FOREST,
                    150.0 + 20.0 * vn(X, Y, 12.0, t[4]) + 10.0 * vn(X, Y, 2.5, t[1]), g)


def test_masked_slope_grey_equals_the_full_evaluation():
    rng = np.random.default_rng(4)
    tables = [rng.uniform(-1, 1, (scene._TABLE, scene._TABLE)) for _ in range(5)]
    X = rng.uniform(-2000, 2000, 20000)
    Y = rng.uniform(-900, 900, 20000)
    assert (np.abs(Y) > scene.FOREST).any() and (np.abs(Y) <= scene.SLOPE_HALF_WIDTH).any()
    assert np.array_equal(scene._slope_grey(X, Y, tables), _slope_grey_everywhere(X, Y, tables))


def test_value_noise_power_of_two_and_general_tables_agree():
    rng = np.random.default_rng(5)
    table = rng.uniform(-1, 1, (16, 16))
    x, y = rng.uniform(-500, 500, (2, 5000))
    fast = scene._value_noise(x, y, 3.7, table)
    # the table tiled 3 x 3 (48: not a power of two, the general path) has
    # the same values at every wrapped index
    general = scene._value_noise(x, y, 3.7, np.tile(table, (3, 3)))
    assert np.array_equal(fast, general)
