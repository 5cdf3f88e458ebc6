"""stick.png draws the landing-slope profile under the jumper (side view,
abscissa world X)."""

import numpy as np
import pytest

from photogram.jump import stick_model
from photogram.jump.stick import ProfileGround
from photogram.jump.synthetic import synthetic_jumper

pytest.importorskip("matplotlib")
from photogram.jump.figure import _profile_in_view, plot_stick_figure  # noqa: E402


def test_the_profile_is_cut_to_the_view_and_interpolated_at_its_ends():
    profile = ProfileGround(x=np.array([0.0, 10.0, 20.0, 40.0]), z=np.array([0.0, -5.0, -15.0,
                                                                             -25.0]))
    gx, gz = _profile_in_view(profile, 1.0, "x", 5.0, 30.0)
    assert np.allclose(gx, [5.0, 10.0, 20.0, 30.0])
    assert np.allclose(gz, [-2.5, -5.0, -15.0, -20.0])
    gx, gz = _profile_in_view(profile, 0.1, "x", 0.5, 1.5)      # dm -> m
    assert np.allclose(gx, [0.5, 1.0, 1.5]) and np.allclose(gz, [-0.25, -0.5, -1.0])
    assert _profile_in_view(profile, 1.0, "flight", 5.0, 30.0) is None
    assert _profile_in_view(profile, 1.0, "x", 50.0, 60.0) is None      # no overlap
    assert _profile_in_view(None, 1.0, "x", 5.0, 30.0) is None


@pytest.fixture(scope="module")
def model():
    s = synthetic_jumper(n=12)
    return stick_model(s["P"], s["d1"], s["d2"], c1=s["c1"], c2=s["c2"])


@pytest.mark.slow
def test_the_profile_changes_the_side_view_only_along_world_x(model, tmp_path):
    O = model.O
    x = np.linspace(O[:, 0].min() - 50, O[:, 0].max() + 50, 5)
    slope = np.polyfit(O[:, 0], O[:, 2], 1)[0]
    profile = ProfileGround(x=x, z=O[:, 2].mean() - 30.0 + slope * (x - O[:, 0].mean()))
    bare = plot_stick_figure(model, tmp_path / "a.png", dpi=40).read_bytes()
    drawn = plot_stick_figure(model, tmp_path / "b.png", dpi=40, profile=profile).read_bytes()
    assert drawn != bare
    flight = plot_stick_figure(model, tmp_path / "c.png", dpi=40, along="flight").read_bytes()
    same = plot_stick_figure(model, tmp_path / "d.png", dpi=40, along="flight",
                             profile=profile).read_bytes()
    assert same == flight
