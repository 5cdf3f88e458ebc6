"""datum = "dependent": DBAT's dependent relative orientation
(``seteoest(s, 'depend', IMNO, [coord])``, niclasborlin/dbat
code/bundle/seteoest.m): the base station's six exterior parameters and
the projection-centre coordinate with the largest signed offset from it
are held fixed.

Simulated networks (photogram.simulation) where the truth is known, and a
DBAT script with ``<cameras><file>``, ``<prior_eo>``, ``<set_initial_values>``
and ``<set_datum ... depend>`` written around DBAT's own CAMCAL files (no
script in DBAT's data uses these elements; its tables and camera file do).
"""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from photogram.adjust.datum import dependent_orientation
from photogram.bundle import adjust
from photogram.errors import GeometryError, InputError
from photogram.project import read_project

from io_fixtures import SHARED


def test_dbat_rule_signed_largest_offset():
    """DBAT takes the largest *signed* offset over x, y, z (not the
    largest absolute one), and every tied coordinate."""
    X0 = np.array([[0.0, 0.0, 0.0], [-9.0, 1.0, 0.5], [2.0, -7.0, 0.0], [1.0, 3.0, 3.0]])
    fixed = dependent_orientation(X0, 0, "longest")
    assert fixed[:6] == [(0, k) for k in range(6)]
    assert fixed[6:] == [(3, 1), (3, 2)]          # y and z of station 4 tie at +3
    assert dependent_orientation(X0, 0, "x")[6:] == [(2, 0)]
    assert dependent_orientation(X0, 2, "y")[:6] == [(2, k) for k in range(6)]
    assert dependent_orientation(X0, 2, "y")[6:] == [(3, 1)]      # 3 - (-7) = 10
    with pytest.raises(GeometryError, match="no station lies in the positive x"):
        dependent_orientation(np.array([[5.0, 0, 0], [1.0, 0, 0]]), 0, "x")
    with pytest.raises(GeometryError, match="at least two stations"):
        dependent_orientation(X0[:1], 0)


def _simulated_project(datum):
    """A simulated self-calibration network (frame of 40 points, 6
    stations, 0.3 px noise, c x0 y0 K1 free), no control."""
    from photogram.simulation.network import frame_network, to_project
    net = frame_network(n_stations=6, n_points=40, sigma=0.3, seed=3)
    p = to_project(net, free_interior=("c", "x0", "y0", "K1"), perturb_points=0.002,
                   perturb_stations=0.002, rng=np.random.default_rng(4))
    p.adjustment.datum = datum
    p.adjustment.sigma_image = 0.3
    p.adjustment.tolerance = 1e-13          # both to the minimum, for the 1e-9 comparison
    p.adjustment.max_iterations = 50
    return p, net


def test_dependent_equals_free_and_fixes_seven():
    """Simulated network: the dependent datum gives the free network's
    sigma0, redundancy and interior orientation with its deviations
    (datum-invariant) to 1e-9 / 1e-6; the base station's six sigmas and the
    fixed coordinate's are 0 (DBAT's definition: those parameters are not
    estimated); the points are the free solution moved by a similarity
    (the shape is invariant) to 1e-9 of the network size."""
    from photogram.init.helmert import apply_helmert, helmert
    free = adjust(_simulated_project("free")[0])
    project, net = _simulated_project("dependent")
    project.adjustment.dependent_station = "S2"
    X0 = project.stations.position.copy()
    dep = adjust(project)
    for s in (free.summary, dep.summary):
        assert s["status"] == "converged"
    assert dep.summary["redundancy"] == free.summary["redundancy"]
    assert dep.summary["sigma0"] == pytest.approx(free.summary["sigma0"], rel=1e-9)
    assert dep.summary["counts"]["exterior"] == free.summary["counts"]["exterior"] - 7
    (name, a), = dep.project.cameras.items()
    b = free.project.cameras[name]
    assert np.allclose(a.values(), b.values(), rtol=1e-9, atol=1e-12)
    for n in ("c", "x0", "y0", "K1"):
        assert dep.camera_sigma[name][n] == pytest.approx(free.camera_sigma[name][n], rel=1e-6)
    assert np.all(dep.station_sigma[1] == 0)
    fixed = dependent_orientation(X0, 1, "longest")
    assert len(fixed) == 7
    j, k = fixed[6]
    assert dep.station_sigma[j, k] == 0 and np.count_nonzero(dep.station_sigma == 0) == 7
    assert dep.project.stations.position[j, k] == pytest.approx(X0[j, k], abs=1e-12)
    P, Q = dep.project.points.xyz, free.project.points.xyz
    moved = apply_helmert(helmert(Q, P), Q)
    assert np.max(np.abs(moved - P)) < 1e-9


# --------------------------------------------------------------------------
# a DBAT script with the elements the issue names, around DBAT's files

DBAT = SHARED / "dbat" / "script" / "camcaldemo"

SCRIPT = """<?xml version="1.0" encoding="UTF-8"?>
<document dbat_script_version="1.0">
  <meta><name>dependent</name><project_unit>m</project_unit></meta>
  <input base_dir="$HERE">
    <images><file format="id,path">images/images.txt</file></images>
    <image_pts><file format="im,id,x,y,sxy">measurements/markpts.txt</file></image_pts>
    <prior_eo>
      <file format="ignored,id,x,y,z,omega,phi,kappa,ignored,ignored,ignored,ignored,ignored,ignored,ignored" units="radian">result/camera_stations.txt</file>
    </prior_eo>
    <cameras><file>c4040z.xml</file></cameras>
  </input>
  <operations>
    <operation>
      <set_initial_values><io><all>default</all></io><eo>loaded</eo></set_initial_values>
    </operation>
    <operation>
      <set_bundle_estimate_params>
        <io><all>true</all><skew>false</skew></io><eo><all>true</all></eo><op>default</op>
      </set_bundle_estimate_params>
    </operation>
    <operation><set_datum ref_cam="REF" ref_base="BASE">depend</set_datum></operation>
    <operation>bundle_adjustment</operation>
  </operations>
</document>
"""


def script_folder(tmp_path, ref="1", base="longest", text=None):
    if not DBAT.is_dir():
        pytest.skip(f"DBAT's camcaldemo script not found at {DBAT}")
    folder = tmp_path / "script"
    shutil.copytree(DBAT, folder)
    (folder / "camcaldemo.xml").unlink()
    script = folder / "dependent.xml"
    script.write_text((text or SCRIPT).replace("REF", ref).replace("BASE", base),
                      encoding="utf-8")
    return script


def test_script_with_camera_file_prior_eo_and_dependent_datum(tmp_path):
    from photogram.io.formats import import_project
    script = script_folder(tmp_path, "3", "longest")
    prj = import_project("dbat", script, tmp_path / "imp")
    p = read_project(prj)
    adj = p.adjustment
    assert (adj.datum, adj.dependent_station, adj.dependent_coordinate) == \
        ("dependent", "3", "longest")
    assert not any(k == "control" for k in p.points.kind)
    # the prior EO (DBAT's own result) are the approximate values
    assert p.stations.position[0] == pytest.approx([0.454946608289835, 1.79384867200132,
                                                    1.46806605634717])
    cam = next(iter(p.cameras.values()))
    assert cam.image_size == (2272, 1704) and not cam.parameters["B2"].free    # c4040z.xml
    assert cam.parameters["c"].value * cam.pixel_size[1] == pytest.approx(7.5)  # io default
    r = adjust(p)
    s = r.summary
    # DBAT's network without control: 4148 observations, 435 - 7 unknowns
    assert s["status"] == "converged" and s["redundancy"] == 3713 + 7
    i = p.stations.names.index("3")
    assert np.all(r.station_sigma[i] == 0)
    X0 = p.stations.position
    j, k = dependent_orientation(X0, i, "longest")[6]
    assert r.station_sigma[j, k] == 0 and np.count_nonzero(r.station_sigma == 0) == 7
    # the base station and the fixed coordinate stay at their prior values
    assert np.allclose(r.project.stations.position[i], X0[i], atol=1e-12)
    assert r.project.stations.position[j, k] == pytest.approx(X0[j, k], abs=1e-12)


@pytest.mark.parametrize("edit,line_has,words", [
    (lambda t: t.replace("<file>c4040z.xml</file>", "<file>nothere.xml</file>"),
     "nothere.xml", "file nothere.xml not found"),
    (lambda t: t.replace("<set_datum", "<set_daturn").replace("</set_datum>", "</set_daturn>"),
     "set_daturn", "unknown operation <set_daturn>"),
    (lambda t: t.replace("<cameras>", "<cameras><lens>1</lens>"), "<lens>",
     "unknown element <lens> in <cameras>"),
    (lambda t: t.replace('units="radian"', ""), "omega,phi,kappa", "has angles but no units"),
    (lambda t: t.replace('ref_base="BASE"', 'ref_base="w"'), "ref_base", "ref_base='w'"),
    (lambda t: t.replace('ref_cam="REF"', 'ref_cam="99"'), "ref_cam", "ref_cam=99 is not"),
])
def test_script_errors_one_line(tmp_path, edit, line_has, words):
    """Bad scripts: one line each, at the script's line (the file is named)."""
    from photogram.io.dbat_script import dbat_script_project
    script = script_folder(tmp_path, text=edit(SCRIPT))
    with pytest.raises(InputError, match=words) as err:
        dbat_script_project(script)
    lines = script.read_text().splitlines()
    assert err.value.file == str(script)
    assert line_has in lines[err.value.line - 1]


def test_prj_round_trip(tmp_path):
    """datum = "dependent" with its two keys is written and read back; a
    bad dependent_coordinate is one line."""
    from photogram.io.formats import import_project
    prj = import_project("dbat", script_folder(tmp_path, "2", "z"), tmp_path / "imp")
    text = prj.read_text()
    assert 'datum = "dependent"' in text and 'dependent_station = "2"' in text
    assert 'dependent_coordinate = "z"' in text
    assert read_project(prj).adjustment.dependent_station == "2"
    prj.write_text(text.replace('datum = "dependent"', 'datum = "free"'))
    assert any("used only with datum" in w for w in read_project(prj).warnings)
    for key, bad in (("dependent_coordinate", '"w"'), ("dependent_station", '"99"')):
        prj.write_text(text.replace(f'{key} = ', f'{key} = {bad} #'))
        with pytest.raises(InputError, match=key) as err:
            read_project(prj)
        assert key in prj.read_text().splitlines()[err.value.line - 1]
