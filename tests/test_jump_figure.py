"""Stick figure (the paper's Fig. 8) and parameter time series: files written
atomically, deterministic bytes."""

import numpy as np
import pytest

from photogram.errors import InputError
from photogram.jump import stick_model
from photogram.jump.synthetic import synthetic_jumper

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

pytest.importorskip("matplotlib")
from photogram.jump.figure import plot_stick_figure, time_series_figure  # noqa: E402

PNG = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def model():
    s = synthetic_jumper(n=20)
    P = s["P"].copy()
    P[7, 1] = np.nan                                   # a gap
    return stick_model(P, s["d1"], s["d2"], c1=s["c1"], c2=s["c2"],
                       cov_points=np.eye(3) * 1e-5 * np.ones((4, 1, 1)),
                       cov_dirs=np.eye(3) * 1e-6 * np.ones((2, 1, 1)))


def test_stick_figure_is_written_and_deterministic(model, tmp_path):
    a = plot_stick_figure(model, tmp_path / "a.png", every=3, dpi=60)
    b = plot_stick_figure(model, tmp_path / "b.png", every=3, dpi=60)
    data = a.read_bytes()
    assert data.startswith(PNG) and len(data) > 5000
    assert data == b.read_bytes()
    assert b"Software" not in data and b"Matplotlib" not in data
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.png", "b.png"]   # no temp left
    c = plot_stick_figure(model, tmp_path / "c.png", every=5, along="flight", dpi=60)
    assert c.read_bytes() != data


def test_time_series_figure(model, tmp_path):
    frame = model.to_frame("deg")
    p = time_series_figure(frame, tmp_path / "t.png", dpi=50)
    data = p.read_bytes()
    assert data.startswith(PNG) and len(data) > 5000
    assert time_series_figure(frame, tmp_path / "u.png", dpi=50).read_bytes() == data
    # without sigma columns and without attrs
    bare = frame[["time", "alpha", "v"]].copy()
    bare.attrs = {}
    assert time_series_figure(bare, tmp_path / "v.png", dpi=50).stat().st_size > 0


def test_figure_errors(model, tmp_path):
    with pytest.raises(InputError):
        plot_stick_figure(model, tmp_path / "x.png", every=0)
    with pytest.raises(InputError):
        plot_stick_figure(model, tmp_path / "x.png", along="z")
    with pytest.raises(InputError):
        plot_stick_figure(model, tmp_path / "missing" / "x.png")
    with pytest.raises(InputError):
        time_series_figure(model.to_frame()[["time"]], tmp_path / "x.png")
    assert not (tmp_path / "x.png").exists()
