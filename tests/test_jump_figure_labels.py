"""stick.png keeps its y labels inside the figure (a steep descent made the
side view tall and its "Z" label was clipped at the left edge)."""

import pytest

from photogram.jump import stick_model
from photogram.jump.synthetic import synthetic_jumper

pytest.importorskip("matplotlib")
import photogram.jump.figure as figure  # noqa: E402

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow


@pytest.mark.parametrize("steepness", [1.0, 5.0])
def test_every_y_label_lies_inside_the_figure(tmp_path, monkeypatch, steepness):
    s = synthetic_jumper(n=30)
    P, c1, c2 = s["P"].copy(), s["c1"].copy(), s["c2"].copy()
    for a in (P, c1, c2):
        a[..., 2] *= steepness                   # 5: a tall side view (13.5 in)
    model = stick_model(P, s["d1"], s["d2"], c1=c1, c2=c2)
    seen = {}
    save = figure._save

    def spy(fig, path, dpi):
        fig.canvas.draw()
        renderer = fig.canvas.get_renderer()
        seen["x0"] = min(min([ax.yaxis.label.get_window_extent(renderer).x0] +
                             [t.get_window_extent(renderer).x0 for t in ax.get_yticklabels()
                              if t.get_text()]) for ax in fig.axes)
        return save(fig, path, dpi)

    monkeypatch.setattr(figure, "_save", spy)
    figure.plot_stick_figure(model, tmp_path / "stick.png", every=3)
    assert seen["x0"] >= 0.0
