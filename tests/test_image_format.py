"""Issue 16, item 10 (image-coordinate plausibility): image points are
checked against the image format of their camera. Coordinates in mm while
the project says px (all in a tiny corner) and px while it says mm (most
outside the format) are refused in one line; they used to converge with no
warning (stations 100 times too far away)."""

import json

import pytest

from field_copy import field_copy
from photogram_cli.main import main

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow


def _scaled(factor):
    def change(text):
        out = []
        for line in text.splitlines():
            if line.startswith("S"):
                s, p, x, y = line.split(",")
                line = f"{s},{p},{float(x) * factor:.5f},{float(y) * factor:.5f}"
            out.append(line)
        return "\n".join(out) + "\n"
    return change


def _run(capsys, prj, tmp_path, command="orient"):
    code = main([command, "-q", *(["--no-report"] if command != "check" else []), str(prj), "--output", str(tmp_path / "out")])
    return code, capsys.readouterr().err.strip().splitlines()


@pytest.mark.parametrize("image_size", [True, False])
def test_mm_read_as_px_is_refused(tmp_path, capsys, image_size):
    # the field cameras have 0.01 mm pixels: mm values are 1/100 of the px values
    replace = {"field_image_points.csv": _scaled(0.01)}
    if not image_size:       # then the format is taken as twice the principal point
        replace["cameras-nominal.toml"] = lambda t: "\n".join(
            ln for ln in t.splitlines() if not ln.startswith("image_size")) + "\n"
    prj = field_copy(tmp_path, **replace)
    for command in ("orient", "check"):
        code, err = _run(capsys, prj, tmp_path, command)
        assert code == 2 and len(err) == 1, err
        assert err[0].startswith(str(prj.parent / "field_image_points.csv") + ":4: ")
        assert "all 21 image points of camera K1 lie within" in err[0]
        assert "they look like mm, not px" in err[0]


def test_px_read_as_mm_is_refused(tmp_path, capsys):
    prj = field_copy(tmp_path, **{"field.prj": lambda t: t.replace('image_unit = "px"',
                                                                   'image_unit = "mm"')})
    code, err = _run(capsys, prj, tmp_path)
    assert code == 2 and len(err) == 1, err
    assert "21 of the 21 image points of camera K1 lie outside its 6.4 x 4.8 mm format" in err[0]


def test_a_point_outside_the_format_is_a_warning(tmp_path, capsys):
    prj = field_copy(tmp_path, **{"field_image_points.csv": lambda t: t.replace(
        "S1,M1,552.44,152.8", "S1,M1,652.44,152.8")})
    code, err = _run(capsys, prj, tmp_path)
    assert code == 0, err
    summary = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert "1 image point(s) lie outside the image format (first: line 4)" in summary["warnings"]
