"""An exposure where a jumper point is not measured (a marker flagged by
photogram track, never guessed): intersect goes on; that point and what
depends on it are empty for that exposure (no sigma of 0), the rest is as
before."""

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

ROOT = Path(__file__).resolve().parents[1]
JUMPS = ROOT / "projects" / "jumps"
NEEDS = [ROOT / "projects/lab/results/cameras.toml", ROOT / "projects/field/results/covariance.npz"]


@pytest.mark.skipif(not all(p.exists() for p in NEEDS), reason="needs make demo's lab and field results")
def test_a_point_missing_at_one_exposure_leaves_a_gap_not_a_zero_sigma(tmp_path):
    for name in ("jumps.prj", "ski_lines.csv"):
        shutil.copy(JUMPS / name, tmp_path / name)
    prj = tmp_path / "jumps.prj"
    text = prj.read_text().replace('"../', f'"{ROOT}/projects/')
    prj.write_text(text)
    rows = (JUMPS / "jumper_points.csv").read_text().splitlines()
    kept = [r for r in rows if not r.startswith("007,") or ",P2," not in r]
    assert len(rows) - len(kept) == 3                      # P2@007 in S1, S2, S3
    (tmp_path / "jumper_points.csv").write_text("\n".join(kept) + "\n")
    run = subprocess.run([sys.executable, "-m", "photogram_cli", "intersect", str(prj)],
                         capture_output=True, text=True, cwd=tmp_path)
    assert run.returncode == 0, run.stderr
    pts = pd.read_csv(tmp_path / "results" / "points3d.csv", dtype={"exposure": str})
    gap = pts[(pts.exposure == "007") & (pts.point == "P2")]
    assert gap[["X", "Y", "Z", "sX", "sY", "sZ"]].isna().all(axis=None)
    rest = pts[~((pts.exposure == "007") & (pts.point == "P2"))]
    assert rest[["X", "sX"]].notna().all(axis=None) and (rest.sX > 0).all()
    ex = pd.read_csv(tmp_path / "results" / "exposures.csv", dtype={"exposure": str})
    e7 = ex[ex.exposure == "007"].iloc[0]
    assert np.isnan(e7.alpha) and np.isfinite(e7.phi) and np.isfinite(e7.v)   # alpha needs P2
    assert ex[ex.exposure != "007"].alpha.notna().all()
