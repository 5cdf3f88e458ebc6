"""An exposure where a jumper point is not measured (a marker flagged by
photogram track, never guessed): intersect goes on; that point and what
depends on it are empty for that exposure (no sigma of 0), the rest is as
before."""

import contextlib
import io
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
JUMPS = ROOT / "projects" / "jumps"


def _intersect(prj, cwd):
    """`photogram intersect --no-report PRJ` run from ``cwd`` through the
    command's entry point in this process (the process boundary is not what
    these tests are about)."""
    from photogram_cli.main import main
    err = io.StringIO()
    with contextlib.chdir(cwd), contextlib.redirect_stdout(io.StringIO()), \
            contextlib.redirect_stderr(err):
        code = main(["intersect", "--no-report", str(prj)])
    assert code == 0, err.getvalue()


def test_a_point_missing_at_one_exposure_leaves_a_gap_not_a_zero_sigma(tmp_path,
                                                                      oriented_projects):
    for name in ("jumps.prj", "ski_lines.csv"):
        shutil.copy(JUMPS / name, tmp_path / name)
    prj = tmp_path / "jumps.prj"
    text = prj.read_text().replace('"../', f'"{oriented_projects}/')
    prj.write_text(text)
    rows = (JUMPS / "jumper_points.csv").read_text().splitlines()
    kept = [r for r in rows if not r.startswith("007,") or ",P2," not in r]
    assert len(rows) - len(kept) == 3                      # P2@007 in S1, S2, S3
    (tmp_path / "jumper_points.csv").write_text("\n".join(kept) + "\n")
    _intersect(prj, tmp_path)
    pts = pd.read_csv(tmp_path / "results" / "points3d.csv", dtype={"exposure": str})
    gap = pts[(pts.exposure == "007") & (pts.point == "P2")]
    assert gap[["X", "Y", "Z", "sX", "sY", "sZ"]].isna().all(axis=None)
    rest = pts[~((pts.exposure == "007") & (pts.point == "P2"))]
    assert rest[["X", "sX"]].notna().all(axis=None) and (rest.sX > 0).all()
    ex = pd.read_csv(tmp_path / "results" / "exposures.csv", dtype={"exposure": str})
    e7 = ex[ex.exposure == "007"].iloc[0]
    assert np.isnan(e7.alpha) and np.isfinite(e7.phi) and np.isfinite(e7.v)   # alpha needs P2
    assert ex[ex.exposure != "007"].alpha.notna().all()


def test_a_ski_seen_in_one_image_is_a_gap_with_a_warning(tmp_path, oriented_projects):
    shutil.copy(JUMPS / "jumper_points.csv", tmp_path / "jumper_points.csv")
    prj = tmp_path / "jumps.prj"
    prj.write_text((JUMPS / "jumps.prj").read_text().replace('"../', f'"{oriented_projects}/'))
    rows = (JUMPS / "ski_lines.csv").read_text().splitlines()
    drop = ("009,S1,L1,", "009,S2,L1,")
    kept = [r for r in rows if not r.startswith(drop)]
    assert len(rows) - len(kept) == 30                     # 15 points in each of 2 images
    (tmp_path / "ski_lines.csv").write_text("\n".join(kept) + "\n")
    _intersect(prj, tmp_path)
    import json
    s = json.loads((tmp_path / "results" / "summary.json").read_text())
    assert any("L1@009 is measured in 1 image(s)" in w for w in s["warnings"])
    lines = pd.read_csv(tmp_path / "results" / "lines3d.csv", dtype={"exposure": str})
    assert not ((lines.exposure == "009") & (lines.line == "L1")).any()
    assert len(lines) == 47
    ex = pd.read_csv(tmp_path / "results" / "exposures.csv", dtype={"exposure": str})
    e9 = ex[ex.exposure == "009"].iloc[0]
    assert np.isnan(e9.delta_phi)                      # the V angle needs both skis
    assert ex[ex.exposure != "009"].delta_phi.notna().all()
