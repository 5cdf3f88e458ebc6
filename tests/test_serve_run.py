"""The run endpoint of photogram measure --serve (photogram/serve/run.py):
refused while the table has unsaved edits (409) or for another command
(400); a real `photogram calibrate` in a subprocess (slow) re-reads the
results folder (sigma0, worst residuals)."""

from __future__ import annotations

import json
import sys

import pytest

from serve_fixtures import Running, lab_copy


@pytest.fixture
def session(tmp_path):
    from photogram.serve.session import Session
    s = Session(lab_copy(tmp_path / "lab", oriented=False),
                run_argv=[sys.executable, "-m", "photogram_cli"])   # as the CLI gives it
    yield s
    s.close()


def test_run_needs_a_saved_table_and_a_known_command(session):
    with Running(session) as r:
        status, body = r.request("POST", "/api/run", {"command": "rm -rf /"})
        assert status == 400 and "choose calibrate, orient, intersect" in body["error"]
        r.request("POST", "/api/edit", {"op": "delete", "oid": 3})
        status, body = r.request("POST", "/api/run", {"command": "calibrate"})
        assert status == 409 and "save the observations first" in body["error"]
        assert not (session.project.folder / "results-typed").exists()
        session.run_argv = None               # a session not started from the CLI
        session.save()
        status, body = r.request("POST", "/api/run", {"command": "orient"})
        assert status == 400 and "needs the server started by" in body["error"]


@pytest.mark.slow
def test_run_calibrate_reads_the_new_results(session):
    """photogram calibrate of lab-typed.prj (README: sigma0 about 1.0, 1.008)
    from the page: rc 0, the page is oriented afterwards, sigma0 and the 20
    worst residuals as in the new results folder."""
    with Running(session) as r:
        assert not r.request("GET", "/api/project")[1]["oriented"]
        status, body = r.request("POST", "/api/run", {"command": "calibrate"})
    assert status == 200 and body["rc"] == 0 and body["message"] == ""
    summary = json.loads((session.project.folder / "results-typed" / "summary.json").read_text())
    assert body["sigma0"] == pytest.approx(summary["sigma0"]) and 0.9 < body["sigma0"] < 1.1
    assert body["project"]["oriented"]
    assert body["project"]["orientation_note"] == \
        f"stations oriented from results-typed/ (calibrate, sigma0 {summary['sigma0']:.2f})"
    worst = body["worst"]
    assert len(worst) == 20 and all(abs(a["w"]) >= abs(b["w"]) for a, b in zip(worst, worst[1:]))
    assert all(w["oid"] is not None for w in worst)
    assert len(body["project"]["residuals"]) == 446
