"""`photogram measure --serve` on the command line: bad input is one line
on stderr and exit 2 (through photogram_cli.main.main), the lock refuses a
second editor; a served page prints exactly the URL line."""

from __future__ import annotations

import sys

from photogram_cli.main import main

from serve_fixtures import lab_copy


def _one_line(capsys):
    err = capsys.readouterr().err.strip()
    assert "\n" not in err and "Traceback" not in err
    return err


def test_missing_project_is_one_line(tmp_path, capsys):
    assert main(["measure", "--serve", str(tmp_path / "nothing.prj")]) == 2
    assert "nothing.prj" in _one_line(capsys)


def test_missing_table_is_one_line(tmp_path, capsys):
    prj = lab_copy(tmp_path / "lab", oriented=False)
    (prj.parent / "lab_image_points.csv").unlink()
    assert main(["measure", "--serve", str(prj)]) == 2
    err = _one_line(capsys)
    assert "lab_image_points.csv" in err and "not found" in err


def test_bad_port_is_one_line(tmp_path, capsys):
    prj = lab_copy(tmp_path / "lab", oriented=False)
    assert main(["measure", "--serve", str(prj), "--port", "70000"]) == 2
    assert "--port 70000" in _one_line(capsys)


def test_second_editor_is_refused(tmp_path, capsys):
    from photogram.serve.session import Session
    prj = lab_copy(tmp_path / "lab", oriented=False)
    first = Session(prj)
    try:
        assert main(["measure", "--serve", str(prj)]) == 2
        err = _one_line(capsys)
        assert "another photogram measure --serve is editing" in err
        assert ".lab_image_points.csv.lock held" in err
    finally:
        first.close()
    second = Session(prj)          # released: the next editor may open it
    second.close()


def test_serve_prints_the_url_and_stops_on_interrupt(tmp_path, monkeypatch, capsys):
    """Ctrl+C (KeyboardInterrupt in serve_forever) ends with exit 0 and the
    lock released."""
    from http.server import ThreadingHTTPServer
    prj = lab_copy(tmp_path / "lab", oriented=False)
    seen = {}

    def interrupted(self, poll_interval=0.5):
        seen["address"] = self.server_address
        seen["run_argv"] = self.session.run_argv
        raise KeyboardInterrupt

    monkeypatch.setattr(ThreadingHTTPServer, "serve_forever", interrupted)
    assert main(["measure", "--serve", str(prj), "-q"]) == 0
    out = capsys.readouterr().out.splitlines()
    port = seen["address"][1]
    assert seen["address"][0] == "127.0.0.1" and port > 0
    assert len(out) == 1 and out[0].startswith(f"measure --serve: http://127.0.0.1:{port}/?token=")
    # the run button runs commands through the same front end and interpreter
    assert seen["run_argv"] == [sys.executable, "-m", "photogram_cli"]
    assert out[0].endswith(" (Ctrl+C to stop)") and len(out[0].split("token=")[1].split()[0]) == 32
    from photogram.serve.session import Session
    Session(prj).close()           # the lock was released


def test_stop_with_unsaved_edits_says_so(tmp_path, monkeypatch, caplog):
    from http.server import ThreadingHTTPServer
    prj = lab_copy(tmp_path / "lab", oriented=False)

    def edit_then_stop(self, poll_interval=0.5):
        self.session.edit({"op": "delete", "oid": 0})
        raise KeyboardInterrupt

    monkeypatch.setattr(ThreadingHTTPServer, "serve_forever", edit_then_stop)
    assert main(["measure", "--serve", str(prj), "-q"]) == 0
    assert any("stopped with unsaved edits" in r.getMessage() for r in caplog.records)
    assert "K1a,T01" in (prj.parent / "lab_image_points.csv").read_text()   # not saved
