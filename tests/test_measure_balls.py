"""A field of balls (bright spheres on a dark background), rendered with
known truth: detection, centres against the true outline ellipse, and the
eccentricity of a ball (outline centre vs the image of its centre)."""

import numpy as np
import pytest

from photogram.measure.detect import detect_targets
from photogram.measure.ellipse import conic_centre, fit_ellipse
from photogram.measure.render import look_at
from photogram.measure.sphere import ball_eccentricity, outline_centre, render_balls

K = np.array([[600.0, 0, 399.5], [0, 600, 299.5], [0, 0, 1]])      # a wide angle


def test_outline_centre_against_points_on_the_outline():
    C = np.array([0.4, -0.25, 1.5])
    R = 0.05
    # rays tangent to the sphere: the cone about C with half angle asin(R / |C|)
    a = C / np.linalg.norm(C)
    alpha = np.arcsin(R / np.linalg.norm(C))
    e1 = np.cross(a, [0.0, 1.0, 0.0])
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(a, e1)
    phi = np.linspace(0, 2 * np.pi, 50, endpoint=False)
    rays = np.cos(alpha) * a + np.sin(alpha) * (np.cos(phi)[:, None] * e1
                                                 + np.sin(phi)[:, None] * e2)
    q = rays @ K.T
    pts = q[:, :2] / q[:, 2:3]
    assert np.allclose(conic_centre(fit_ellipse(pts)), outline_centre(K, C, R), atol=1e-8)
    # on the optical axis there is no eccentricity; off it, it points outwards
    assert np.allclose(ball_eccentricity(K, np.array([0.0, 0.0, 2.0]), R), 0, atol=1e-12)
    e = ball_eccentricity(K, C, R)
    p = K @ C
    assert e @ (p[:2] / p[2] - K[:2, 2]) > 0


@pytest.mark.parametrize("name,kw", [("good", dict(blur=0.7, noise=2.0, jpeg=90)),
                                     ("harsh", dict(blur=1.3, noise=5.0, jpeg=60))])
def test_field_of_balls(name, kw):
    rng = np.random.default_rng(4)
    gx, gy = np.meshgrid(np.linspace(-0.6, 0.6, 6), np.linspace(-0.4, 0.4, 4))
    centres = np.column_stack([gx.ravel(), gy.ravel(), rng.uniform(0, 0.3, gx.size)])
    Rm, t = look_at((0.2, -1.0, 1.0), (0, 0, 0.1), up=(0, 0, 1))
    img = render_balls(centres, 0.02, K, Rm, t, (800, 600), seed=1, **kw)
    det = detect_targets(img, "bright", min_diameter=4, max_diameter=80)
    C = centres @ Rm.T + t
    outline = np.array([outline_centre(K, c, 0.02) for c in C])
    ecc = np.array([ball_eccentricity(K, c, 0.02) for c in C])
    h = C @ K.T
    image_of_centre = h[:, :2] / h[:, 2:3]
    d = np.linalg.norm(det.xy[:, None] - outline[None], axis=2)
    j = d.argmin(axis=1)
    assert (d.min(axis=1) < 0.5).all() and len(set(j)) == len(j)    # only balls accepted
    assert len(j) == 23 and det.counts()["border"] == 1             # one cut by the border

    def rms(e):
        return float(np.sqrt((e ** 2).sum(axis=1).mean()))

    r_out = rms(det.xy - outline[j])
    r_raw = rms(det.xy - image_of_centre[j])
    r_cor = rms(det.xy - ecc[j] - image_of_centre[j])
    print(f"{name}: {2 * det.axes[:, 0].min():.1f}-{2 * det.axes[:, 0].max():.1f} px; "
          f"against the outline centre {r_out:.4f} px; against the image of the ball's "
          f"centre {r_raw:.4f} px, corrected {r_cor:.4f} px (eccentricity up to "
          f"{np.abs(ecc).max():.3f} px)")
    assert r_out < (0.025 if name == "good" else 0.035)            # measured 0.015, 0.022
    assert r_cor < 0.5 * r_raw
