"""Importers on the real files DBAT ships (../shared/data/dbat/script/ and
pmexports/), each imported with ``photogram import`` and adjusted, against
DBAT's own reports (script/*/result/report.txt, dbatexports/*.txt).

Figures are compared to DBAT's printed digits: within half a unit of the
last printed digit (helpers of tests/test_dbat_reference.py). DBAT stops
at a relative change of 1e-6 ("Convergence tolerance: 1e-06" in its
reports), which leaves a few parameters short of their printed digits: a
value may then differ by at most 2e-5 of that parameter's deviation (the
cases are named in the tests; photogram converges to 1e-12 here). The
measured figures are in docs/interoperability.md, sections 2.1 and 2.2
(``pytest -s tests/test_io_dbat_real.py`` prints them).
"""

from __future__ import annotations

import contextlib
import io
import logging
from pathlib import Path

import numpy as np
import pytest

from photogram.bundle import adjust
from photogram.errors import InputError
from photogram.project import read_project

from io_fixtures import SHARED

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow

DBAT = SHARED / "dbat"
SCRIPTS = DBAT / "script"
PM = DBAT / "pmexports"
REPORTS = DBAT / "dbatexports"
CONTROL = SCRIPTS / "camcaldemo" / "reference" / "camcal-fixed.txt"

if not (SCRIPTS.is_dir() and PM.is_dir() and REPORTS.is_dir()):
    pytest.skip(f"DBAT's scripts and exports not found under {DBAT}", allow_module_level=True)

from test_dbat_reference import DBAT_NAMES, dbat_report, printed, to_mm, pixel_size  # noqa: E402


def cli_import(*args) -> int:
    from photogram_cli.main import main
    with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
        return main(["import", *map(str, args), "-q"])


def imported(tmp_path, *args):
    """The project ``photogram import ARGS --to tmp`` writes."""
    assert cli_import(*args, "--to", tmp_path / "imp") == 0
    (prj,) = (tmp_path / "imp").glob("*.prj")
    return read_project(prj)


def converged(project):
    """Adjusted to DBAT's minimum (photogram's default tolerance stops a
    few units of the 7th digit short of it on CAMCAL)."""
    project.adjustment.tolerance = 1e-12
    project.adjustment.max_iterations = 50
    return adjust(project)


def interior_mismatches(result, report, loose=()) -> list[str]:
    """Each interior parameter and its deviation against DBAT's report
    (mm): printed digits; for the names in ``loose`` also within 2e-5 of
    the deviation (DBAT's convergence)."""
    (name, cam), = result.project.cameras.items()
    ps = pixel_size(report)
    values = to_mm({n: p.value for n, p in cam.parameters.items()}, ps)
    sigmas = to_mm(result.camera_sigma[name], ps)
    bad, rows = [], []
    for n, heading in DBAT_NAMES.items():
        ref = report["camera"][heading]
        value, half = printed(ref["value"])
        dev, dev_half = printed(ref["deviation"])
        slack = 2e-5 * dev if n in loose else 0.0
        rows.append(f"{n} {values[n]:.7g} ({ref['value']}, {abs(values[n] - value) / half / 2:.2f}"
                    f" unit) sd {abs(sigmas[n]):.4g} ({ref['deviation']}, "
                    f"{abs(abs(sigmas[n]) - dev) / dev_half / 2:.2f} unit)")
        if abs(values[n] - value) > max(half, slack):
            bad.append(f"{n}: {values[n]:.7g} vs DBAT {ref['value']}")
        if abs(abs(sigmas[n]) - dev) > dev_half:
            bad.append(f"sigma {n}: {abs(sigmas[n]):.4g} vs DBAT {ref['deviation']}")
    print("interior (mm; DBAT's printed value, |ours - DBAT| in units of its last digit):\n  "
          + "\n  ".join(rows))
    return bad


def station_mismatches(result, report) -> list:
    """Every station's six deviations against DBAT's report to the printed
    digits, and its values to the printed digits or 0.5 % of the deviation
    (DBAT prints 1e-6 m and 1e-6 deg, below its convergence: measured
    camcaldemo 0.71 unit = 0.27 % of the deviation, sxb 20 units of 1e-6 m
    = 0.02 %; angles in degrees)."""
    st, bad = result.project.stations, []
    for k, photo in report["photos"].items():
        i = st.names.index(str(k))
        values = list(st.position[i]) + list(np.degrees(st.angles[i]))
        sigmas = list(result.station_sigma[i, :3]) + list(np.degrees(result.station_sigma[i, 3:]))
        for j, name in enumerate(("Xc", "Yc", "Zc", "Omega", "Phi", "Kappa")):
            value, half = printed(photo[name]["value"])
            dev, dev_half = printed(photo[name]["deviation"])
            diff = values[j] - value
            if j >= 3:
                diff = (diff + 180.0) % 360.0 - 180.0
            if abs(diff) > max(half, 0.005 * dev):
                bad.append((k, name, values[j], photo[name]["value"]))
            if abs(sigmas[j] - dev) > dev_half:
                bad.append((k, name, sigmas[j], photo[name]["deviation"]))
    return bad


def summary_matches(result, report):
    s = result.summary
    assert s["status"] == "converged"
    assert s["redundancy"] == report["redundancy"]
    value, half = printed(report["sigma0"])
    print(f"sigma0 {s['sigma0']:.7f} (DBAT {report['sigma0']}), redundancy {s['redundancy']} "
          f"(DBAT {report['redundancy']}), unknowns {s['counts']['unknowns']}")
    assert abs(s["sigma0"] - value) <= half, (s["sigma0"], report["sigma0"])


# --------------------------------------------------------------------------
# DBAT scripts


def test_camcaldemo_script_reproduces_dbat(tmp_path):
    """script/camcaldemo: interior start values 'default' (cc = focal,
    pp = sensor centre), all interior parameters but skew free, fixed
    control: sigma0 1.6148, redundancy 3725, 423 unknowns, every interior
    parameter and deviation and the 21 stations' six deviations to DBAT's
    printed digits (values: station_mismatches); P2 within 2e-5 of its
    deviation (DBAT's script run printed -4.41171e-05, its pmexport run of
    the same network -4.41172e-05; the minimum is -4.411716e-05)."""
    p = imported(tmp_path, "dbat", SCRIPTS / "camcaldemo" / "camcaldemo.xml")
    cam = next(iter(p.cameras.values()))
    assert cam.parameters["c"].value * cam.pixel_size[1] == pytest.approx(7.5)   # focal
    assert [n for n, q in cam.parameters.items() if not q.free] == ["B2"]
    assert p.adjustment.datum == "control" and p.stations.names[0] == "1"
    result = converged(p)
    report = dbat_report(SCRIPTS / "camcaldemo" / "result" / "report.txt")
    summary_matches(result, report)
    assert result.summary["counts"]["unknowns"] == 423
    assert interior_mismatches(result, report, loose=("P2",)) == []
    assert station_mismatches(result, report) == []


def test_sxb_script_reproduces_dbat(tmp_path):
    """script/sxb: two image-point files with their own sxy, control and
    check points from one file, interior 'loaded' and fixed, weighted
    control: sigma0 1.1786, redundancy 1261, check-point differences and
    every station's six deviations to DBAT's printed digits (values:
    station_mismatches)."""
    p = imported(tmp_path, "dbat", SCRIPTS / "sxb" / "sxb.xml")
    assert p.adjustment.datum == "weighted"
    assert not any(q.free for q in next(iter(p.cameras.values())).parameters.values())
    result = converged(p)
    report = dbat_report(SCRIPTS / "sxb" / "result" / "report.txt")
    summary_matches(result, report)
    check = result.summary["check_points"]
    for pid, d in zip(check["ids"], check["differences"]):
        ref = [printed(v) for v in report["check"][pid]]
        assert all(abs(x - r) <= h for x, (r, h) in zip(d, ref)), (pid, d, ref)
    assert station_mismatches(result, report) == []


# --------------------------------------------------------------------------
# PhotoModeler exports (DBAT's camcal runs: control from camcal-fixed.txt,
# camera freed as "Calibration: yes (cc px py as K1 K2 K3 P1 P2)")


@pytest.mark.parametrize("export,report,loose", [
    ("camcal-pmexport.txt", "camcal-dbatreport.txt", ()),
    # DBAT's 6 iterations stop 1.2e-6 and 0.9e-6 of the deviation short in K2, K3
    ("camcal-pmexport5.txt", "camcal-dbatreport5.txt", ("K2", "K3")),
])
def test_pmexport_reproduces_dbat(tmp_path, export, report, loose):
    p = imported(tmp_path, "pmexport", PM / export, "--control", CONTROL, "--free", "all")
    assert p.adjustment.datum == "control"
    assert np.allclose(p.image_points.sigma, 0.1)                 # px, as DBAT reads them
    result = converged(p)
    rep = dbat_report(REPORTS / report)
    summary_matches(result, rep)
    counts = result.summary["counts"]
    n_io, n_eo, n_op = (int(v) for v in __import__("re").search(
        r"Number of params:\s+\d+ \((\d+) IO, (\d+) EO, (\d+) OP\)",
        (REPORTS / report).read_text()).groups())
    assert (counts["interior"], counts["exterior"], counts["points"]) == (n_io, n_eo, n_op)
    assert interior_mismatches(result, rep, loose=loose) == []


def test_pmexport_camera_fixed_unless_freed(tmp_path):
    """Without --free the camera is PhotoModeler's and stays fixed (as
    DBAT's prob2dbatstruct); the control comes from the control file."""
    p = imported(tmp_path, "pmexport", PM / "camcal-pmexport.txt", "--control", CONTROL)
    cam = p.cameras["pm"]
    assert not any(q.free for q in cam.parameters.values())
    assert cam.parameters["c"].value * cam.pixel_size[1] == pytest.approx(7.4653)
    ctrl = [i for i, k in enumerate(p.points.kind) if k == "control"]
    assert sorted(p.points.ids[i] for i in ctrl) == ["1001", "1002", "1003", "1004"]
    # the control file's coordinates, not PhotoModeler's adjusted ones
    assert np.array_equal(p.points.xyz[ctrl[0]] % 1, [0.0, 0.0, 0.0])


def test_pmexport_one_ray_point_fails_like_dbat(tmp_path, caplog):
    """camcal-pmexport-1ray: point 88 keeps one mark. DBAT: 4116
    observations, redundancy 3693, "structurally rank deficient". The
    import has DBAT's 4116 observations and warns; the imported project is
    refused with one line naming the point and its row."""
    rep = (REPORTS / "camcal-dbatreport-1ray.txt").read_text()
    assert "structurally rank deficient" in rep and "4116 (4116 IP" in rep
    with caplog.at_level(logging.WARNING, logger="photogram"):
        assert cli_import("pmexport", PM / "camcal-pmexport-1ray.txt", "--control", CONTROL,
                          "--free", "all", "--to", tmp_path / "imp") == 0
    assert "point(s) 88 are marked on one photo only" in caplog.text
    (prj,) = (tmp_path / "imp").glob("*.prj")
    rows = (tmp_path / "imp" / "camcal-pmexport-1ray_image_points.csv").read_text().splitlines()
    assert sum(1 for r in rows if r and r[0].isdigit()) * 2 == 4116
    with pytest.raises(InputError, match="point 88 is seen in 1 image") as err:
        read_project(prj)
    assert err.value.line and "88" in rows[err.value.line - 1]


def test_pmexport_missing_observations(tmp_path, caplog):
    """camcal-pmexport-missing-obs: points 13 and 60 have no marks. DBAT
    keeps them as unknowns (423) and fails ("structurally rank deficient",
    redundancy 3641 of 4064 observations). The import has DBAT's 4064
    observations, leaves the two points out with a warning, and adjusts:
    redundancy 3641 + 6."""
    with caplog.at_level(logging.WARNING, logger="photogram"):
        p = imported(tmp_path, "pmexport", PM / "camcal-pmexport-missing-obs.txt", "--control",
                     CONTROL, "--free", "all")
    assert "13, 60 have no marked points" in caplog.text
    rep = (REPORTS / "camcal-dbatreport-missing-obs.txt").read_text()
    assert "structurally rank deficient" in rep and "Redundancy              3641" in rep
    assert 2 * len(p.image_points) == 4064 and "13" not in p.points.ids
    s = adjust(p).summary
    assert s["status"] == "converged" and s["redundancy"] == 3641 + 6


def test_pmexport_no_datum_is_free_and_dependent(tmp_path):
    """DBAT's no-datum run (no control file) fails: "Numerical rank: 428
    (deficiency: 7)", redundancy 3713. Imported without --control the
    datum is free (inner constraints): redundancy 3713 + 7; DBAT's
    dependent relative orientation gives the same sigma0 and interior
    orientation (datum-invariant) with 7 parameters fixed."""
    p = imported(tmp_path, "pmexport", PM / "camcal-pmexport.txt", "--free", "all")
    rep = (REPORTS / "camcal-dbatreport-no-datum.txt").read_text()
    assert "Numerical rank: 428 (deficiency: 7)" in rep
    assert p.adjustment.datum == "free"
    free = adjust(p)
    assert free.summary["redundancy"] == 3713 + 7
    p.adjustment.datum = "dependent"
    dep = adjust(p)
    assert dep.summary["redundancy"] == 3713 + 7
    assert dep.summary["counts"]["exterior"] == 126 - 7
    assert dep.summary["sigma0"] == pytest.approx(free.summary["sigma0"], rel=1e-9)
    a, b = dep.project.cameras["pm"], free.project.cameras["pm"]
    assert np.allclose(a.values(), b.values(), rtol=1e-7, atol=1e-20)
    for n in DBAT_NAMES:
        assert dep.camera_sigma["pm"][n] == pytest.approx(free.camera_sigma["pm"][n], rel=1e-6)


# --------------------------------------------------------------------------
# bad input: one line each


def test_pmexport_broken_block(tmp_path):
    """A photo block that lost its camera line."""
    lines = (PM / "camcal-pmexport5.txt").read_text(encoding="latin-1").splitlines()
    k = next(i for i, ln in enumerate(lines) if ln.split()[:1] == ["1"]
             and len(ln.split()) == 11)                   # photo 1's camera line
    bad = tmp_path / "bad.txt"
    bad.write_text("\n".join(lines[:k] + lines[k + 1:]) + "\n", encoding="latin-1")
    from photogram.io.pmexport import read_pmexport
    with pytest.raises(InputError, match="photo 1: expected a line starting with 1 "
                                         r"\(camera sigmas\), found '2 ") as err:
        read_pmexport(bad)
    assert err.value.line == k + 2 and "6 lines" in (err.value.hint or "")


def test_pmexport_latin1_names_and_no_image_size(tmp_path):
    """Latin-1 file names; line 2 without WIDTH HEIGHT (then the size is
    given with --image-size, or read from the first photo's image file)."""
    lines = (PM / "camcal-pmexport5.txt").read_text(encoding="latin-1").splitlines()
    lines[1] = " 0.000500 20"
    lines[5] = lines[5].replace("P8250021", "Bild_Süd_21")
    src = tmp_path / "pm.txt"
    src.write_bytes(("\n".join(lines) + "\n").encode("latin-1"))
    assert cli_import("pmexport", src, "--to", tmp_path / "a") == 2      # no size: one line
    p = imported(tmp_path, "pmexport", src, "--image-size", "2272,1704")
    assert p.cameras["pm"].image_size == (2272, 1704)


def test_pmexport_image_size_from_the_image_file(tmp_path):
    """No WIDTH HEIGHT on line 2: as DBAT's loadpm, the size of the first
    photo's image file (here beside the export, under its own name)."""
    import cv2
    lines = (PM / "camcal-pmexport5.txt").read_text(encoding="latin-1").splitlines()
    lines[1] = " 0.000500 20"
    src = tmp_path / "pm.txt"
    src.write_text("\n".join(lines) + "\n", encoding="latin-1")
    name = lines[5].split(maxsplit=1)[1].strip()           # data/dbat/images/cam/P8250021.JPG
    (tmp_path / Path(name).parent).mkdir(parents=True)
    cv2.imwrite(str(tmp_path / name), np.zeros((1704, 2272), np.uint8))
    p = imported(tmp_path, "pmexport", src)
    assert p.cameras["pm"].image_size == (2272, 1704)


def test_pmexport_zero_sigmas(tmp_path, caplog):
    """DBAT's rule: all marked-point sigmas 0 -> 1 px for all; zero sigmas
    among non-zero ones get 1 px here, with a warning (DBAT gives them no
    finite weight)."""
    from photogram.io.pmexport import pmexport_project
    lines = (PM / "camcal-pmexport5.txt").read_text(encoding="latin-1").splitlines()
    marks = [i for i, ln in enumerate(lines) if len(ln.split()) == 6
             and ln.split()[4] == "0.10000"]
    zero = list(lines)
    for i in marks:
        zero[i] = zero[i].replace("0.10000", "0.00000")
    src = tmp_path / "zero.txt"
    src.write_text("\n".join(zero) + "\n", encoding="latin-1")
    with caplog.at_level(logging.WARNING, logger="photogram"):
        p = pmexport_project(src, control=CONTROL)
    assert np.all(p.image_points.sigma == 1.0) and "every marked-point sigma is 0" in caplog.text
    mixed = list(lines)
    for i in marks[:3]:
        mixed[i] = mixed[i].replace("0.10000", "0.00000")
    src.write_text("\n".join(mixed) + "\n", encoding="latin-1")
    with caplog.at_level(logging.WARNING, logger="photogram"):
        p = pmexport_project(src, control=CONTROL)
    assert np.count_nonzero(p.image_points.sigma == 1.0) == 3
    assert np.count_nonzero(p.image_points.sigma == 0.1) == len(p.image_points) - 3
    assert "3 marked point(s) have sigma 0 among others" in caplog.text


@pytest.mark.parametrize("lens", [2, 4, -1])
def test_camcaldemo_script_with_other_lens_models(tmp_path, lens):
    """The camcaldemo script with ``<model>N</model>`` in its camera file
    imports a camera of DBAT's lens model N (docs/camera-models.md 4.5; models
    1, 2 and -1 have no aspect and skew, so ``<all>true</all>`` frees 8
    parameters) and reproduces sigma0 and redundancy of DBAT's CAMCAL report
    for that model (camcal-dbatreport-modelN.txt: the same network, same
    control)."""
    import shutil
    from photogram.project.dbat_tables import DBAT_LENS_MODELS
    folder = tmp_path / "script"
    shutil.copytree(SCRIPTS / "camcaldemo", folder)
    for xml in folder.rglob("*.xml"):
        text = xml.read_text(encoding="utf-8")
        if "<model>3</model>" in text:
            xml.chmod(0o644)
            xml.write_text(text.replace("<model>3</model>", f"<model>{lens}</model>"),
                           encoding="utf-8")
    p = imported(tmp_path, "dbat", folder / "camcaldemo.xml")
    cam = next(iter(p.cameras.values()))
    assert cam.model == DBAT_LENS_MODELS[lens]
    assert sum(q.free for q in cam.parameters.values()) == (8 if lens in (2, -1) else 9)
    result = converged(p)
    report = dbat_report(REPORTS / f"camcal-dbatreport-model{lens}.txt")
    summary_matches(result, report)
