"""Issue 16, item 21 (engine cases): a 1e308 approximation and a LinAlgError
(e.g. from angles in the wrong unit) end as one line and exit code 2, not
as "internal error" with exit 1."""

import numpy as np
import pytest

from field_copy import field_copy
from photogram_cli.main import main


def _run(capsys, prj, tmp_path):
    code = main(["orient", "--no-report", "-q", str(prj), "--output", str(tmp_path / "out")])
    err = capsys.readouterr().err.strip().splitlines()
    return code, err


@pytest.mark.parametrize("table, old, new, where", [
    ("field_stations.csv", "S1,K1,299.3,", "S1,K1,1e308,", "field_stations.csv:4: station S1: X0 Y0 Z0 hold 1e+308"),
    ("field_stations.csv", "S2,K2,669.2,488.6,-346.0,-107.60000000000001,",
     "S2,K2,669.2,488.6,-346.0,1e308,", "field_stations.csv:5: station S2: omega phi kappa"),
    ("field_points.csv", "T1,tie,,,", "T1,tie,1e308,0,0", "field_points.csv:19: point T1: X Y Z hold 1e+308"),
])
def test_absurd_approximation_is_one_line(tmp_path, capsys, table, old, new, where):
    def change(text):
        assert old in text
        return text.replace(old, new)
    prj = field_copy(tmp_path, **{table: change})
    code, err = _run(capsys, prj, tmp_path)
    assert code == 2 and len(err) == 1, err
    assert err[0].startswith(str(prj.parent / table)) and where in err[0]
    assert "beyond" in err[0]


def test_linalg_error_in_the_engine_is_one_line(tmp_path, capsys, monkeypatch):
    import photogram.adjust.solver as solver

    def singular(*args, **kwargs):
        raise np.linalg.LinAlgError("Singular matrix")
    monkeypatch.setattr(solver, "schur_solve", singular)
    prj = field_copy(tmp_path)
    code, err = _run(capsys, prj, tmp_path)
    assert code == 2 and len(err) == 1, err
    assert err[0].startswith(str(prj)) and "singular or non-finite system" in err[0]
    assert "internal error" not in err[0]
