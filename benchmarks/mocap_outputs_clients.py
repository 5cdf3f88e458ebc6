"""Are the outputs of ``photogram mocap`` and ``photogram export`` readable
by the biomechanists' own tools? (issue 20, item 6)

Runs ``photogram mocap`` on projects/ski-ptz/ski-ptz-estimate.prj
(SIMULATED: pan-tilt cameras, rotations estimated) and on
projects/pose2sim-demo/demo.prj (REAL OpenPose detections of Pose2Sim's
demo, when /work/shared/data is there), exports each results folder with
``photogram export trc|c3d|mot|csv``, then loads every file with each client
that is installed and compares the values read back with photogram's own
tables (joints3d.csv, metrics.csv, rotations.csv):

* OpenSim (``pip install opensim``): ``TimeSeriesTable`` and the legacy
  ``Storage`` for .mot, ``TimeSeriesTableVec3`` and ``MarkerData`` for .trc;
* Pose2Sim (``Pose2Sim.common.read_trc`` / ``read_mot``; installed with
  ``pip install --no-deps pose2sim rtoml anytree``: its readers need
  neither its 1.9 GB of dependencies nor a GPU);
* ezc3d (the C3D library OpenSim's C3DFileAdapter is built on; the PyPI
  opensim wheel has no C3DFileAdapter) for .c3d;
* pandas for the exported CSV.

Tolerance: ``max |read - table| / max(|table|, 1) <= 1e-6``, except where
photogram's table itself is rounded more coarsely than the file: mocap's own
joints3d.trc/.c3d hold every digit while joints3d.csv has 5 decimals (m),
so they are compared to 5e-6 m (+ float32 for C3D).

A harsher case, not tuned on: the same folder with gaps (12 % of the joint
samples blanked, the last joint included, and 10 % of the angles), exported
again and read by every client: which client reads the gaps as NaN.

Usage: ``python benchmarks/mocap_outputs_clients.py [--out DIR] [--reuse]``.
"""

from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
import traceback
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from photogram.geometry import opk_to_matrix  # noqa: E402
from photogram.io.mocap_results import pan_tilt_roll  # noqa: E402
from photogram_cli.main import main  # noqa: E402

PROJECTS = {"ski-ptz-estimate (simulated)": ROOT / "projects/ski-ptz/ski-ptz-estimate.prj",
            "pose2sim-demo (real)": ROOT / "projects/pose2sim-demo/demo.prj"}
TOL = 1e-6
CSV_ROUNDING_M = 5e-6


def client_versions() -> dict:
    out = {}
    for name, module in (("opensim", "opensim"), ("pose2sim", "Pose2Sim"), ("ezc3d", "ezc3d")):
        try:
            import importlib
            import logging
            logging.getLogger().setLevel(logging.ERROR)    # Pose2Sim's "GUI not available"
            mod = importlib.import_module(module)
            if name == "pose2sim":
                importlib.import_module("Pose2Sim.common")
            out[name] = str(getattr(mod, "__version__", "?"))
        except Exception:                                   # absent or broken: not checked
            out[name] = None
    if out["opensim"]:
        import opensim
        opensim.Logger.removeFileSink()            # no opensim.log in the working folder
        opensim.Logger.setLevelString("off")       # refusals are reported in the table
    return out


# --------------------------------------------------------------------------
# photogram's own tables (the reference)
# --------------------------------------------------------------------------
def reference(folder: Path) -> dict:
    joints = pd.read_csv(folder / "joints3d.csv", comment="#")
    names = [c[:-2] for c in joints.columns if c.endswith("_X")]
    metrics = pd.read_csv(folder / "metrics.csv", comment="#")
    ref = {"time": joints["time"].to_numpy(float), "joint_names": names,
           "joints": np.stack([joints[[f"{j}_{a}" for a in "XYZ"]].to_numpy(float)
                               for j in names], 1),
           "metrics": metrics}
    if (folder / "rotations.csv").is_file():
        rot = pd.read_csv(folder / "rotations.csv", comment="#")
        cams = list(dict.fromkeys(rot["camera"]))
        per = {}
        for c in cams:
            rows = rot[rot["camera"] == c].sort_values("frame")
            a = pan_tilt_roll(opk_to_matrix(np.radians(
                rows[["omega", "phi", "kappa"]].to_numpy(float))))
            for k, what in enumerate(("pan", "tilt", "roll")):
                per[f"{c}_{what}"] = a[:, k]
        ref["rotations"] = per
    return ref


def error(read, table, angles=False) -> float:
    """max |read - table| / max(|table|, 1); inf if shapes or gaps differ;
    angles compared modulo 360 deg."""
    a, b = np.asarray(read, float), np.asarray(table, float)
    if a.shape != b.shape or not np.array_equal(np.isnan(a), np.isnan(b)):
        return np.inf
    ok = ~np.isnan(b)
    d = a[ok] - b[ok]
    if angles:
        d = (d + 180.0) % 360.0 - 180.0
    return float(np.max(np.abs(d) / np.maximum(np.abs(b[ok]), 1.0))) if d.size else 0.0


def yup_to_zup(xyz):
    return xyz[..., [2, 0, 1]]


# --------------------------------------------------------------------------
# the clients' readers: each returns (times, {column: values}) or (times, (n, J, 3), names)
# --------------------------------------------------------------------------
def opensim_table(path):
    import opensim
    t = opensim.TimeSeriesTable(str(path))
    M = np.array(t.getMatrix().to_numpy()) if t.getNumRows() else \
        np.zeros((0, t.getNumColumns()))
    return np.asarray(t.getIndependentColumn()), dict(zip(t.getColumnLabels(), M.T))


def opensim_storage(path):
    import opensim
    s = opensim.Storage(str(path))
    labels = s.getColumnLabels()
    labels = [labels.get(i) for i in range(1, labels.getSize())]     # without "time"
    times = opensim.ArrayDouble()
    s.getTimeColumn(times)
    cols = {}
    for name in labels:
        v = opensim.ArrayDouble()
        s.getDataColumn(name, v)
        cols[name] = np.array([v.get(i) for i in range(v.getSize())])
    return np.array([times.get(i) for i in range(times.getSize())]), cols


def pose2sim_mot(path):
    from Pose2Sim import common
    data, time_col, _ = common.read_mot(str(path))
    return time_col.to_numpy(float), {c: data[c].to_numpy(float) for c in data.columns}


def opensim_trc(path):
    import opensim
    t = opensim.TimeSeriesTableVec3(str(path))
    names = list(t.getColumnLabels())
    flat = t.flatten()                 # kept alive: its matrix is a view (segfault otherwise)
    M = np.array(flat.getMatrix().to_numpy()).reshape(t.getNumRows(), len(names), 3)
    assert t.getTableMetaDataAsString("Units") == "m"
    return np.asarray(t.getIndependentColumn()), yup_to_zup(M), names


def opensim_markerdata(path):
    import opensim
    md = opensim.MarkerData(str(path))
    names = md.getMarkerNames()
    names = [names.get(i) for i in range(names.getSize())]
    n = md.getNumFrames()
    xyz = np.empty((n, len(names), 3))
    for i in range(n):
        frame = md.getFrame(i)
        for k in range(len(names)):
            v = frame.getMarker(k)
            xyz[i, k] = (v[0], v[1], v[2])
    times = np.array([md.getFrame(i).getFrameTime() for i in range(n)])
    return times, yup_to_zup(xyz), names


def pose2sim_trc(path):
    from Pose2Sim import common
    data, _, time_col, markers, _ = common.read_trc(str(path))
    xyz = data.to_numpy(float).reshape(len(data), len(markers), 3)
    return time_col.to_numpy(float), yup_to_zup(xyz), list(markers)


def ezc3d_points(path):
    import ezc3d
    c = ezc3d.c3d(str(path))
    p = c["parameters"]["POINT"]
    assert p["UNITS"]["value"][0].strip() == "mm"
    rate = float(p["RATE"]["value"][0])
    xyz = np.transpose(c["data"]["points"][:3], (2, 1, 0)) / 1000.0          # (n, J, 3) m
    names = [s.strip() for s in p["LABELS"]["value"]]
    return np.arange(xyz.shape[0]) / rate, xyz, names


def pandas_csv(path):
    t = pd.read_csv(path)
    names = [c[:-2] for c in t.columns if c.endswith("_X")]
    xyz = np.stack([t[[f"{j}_{a}" for a in "XYZ"]].to_numpy(float) for j in names], 1)
    return t["time"].to_numpy(float), xyz, names


MOT_CLIENTS = {"opensim": [("TimeSeriesTable", opensim_table), ("Storage", opensim_storage)],
               "pose2sim": [("common.read_mot", pose2sim_mot)]}
TRC_CLIENTS = {"opensim": [("TimeSeriesTableVec3", opensim_trc),
                           ("MarkerData", opensim_markerdata)],
               "pose2sim": [("common.read_trc", pose2sim_trc)]}
C3D_CLIENTS = {"ezc3d": [("ezc3d.c3d", ezc3d_points)]}
CSV_CLIENTS = {"pandas": [("read_csv", pandas_csv)]}


# --------------------------------------------------------------------------
def check_columns(reader, path, times, table: dict, angles=False):
    t, cols = reader(path)
    errs = [error(t, times)]
    for name, values in table.items():
        errs.append(error(cols[name], values, angles) if name in cols else np.inf)
    return max(errs), len(table)


def check_points(reader, path, times, joints, names, tol_abs=None, t_offset=0.0, t_tol=0.0):
    t, xyz, got = reader(path)
    if list(got) != list(names):
        return np.inf, 0
    if tol_abs is not None:                          # table rounded: absolute, scaled to TOL
        ok = ~np.isnan(joints)
        if xyz.shape != joints.shape or not np.array_equal(np.isnan(xyz), np.isnan(joints)):
            return np.inf, len(names)
        d = float(np.max(np.abs(xyz[ok] - joints[ok]) - tol_abs(joints[ok])))
        e_pts = max(d, 0.0)                          # 0 when within the table's rounding
    else:
        e_pts = error(xyz, joints)
    e_t = max(float(np.max(np.abs(t - times - t_offset))) - t_tol, 0.0) \
        if len(t) == len(times) else np.inf
    return max(e_pts, e_t), len(names)


def run_checks(folder: Path, exports: Path, versions: dict, label: str, rows: list) -> None:
    ref = reference(folder)
    m = ref["metrics"]
    angles = {c: m[c].to_numpy(float) for c in ("knee_flexion_r", "knee_flexion_l",
                                                 "hip_flexion_r", "hip_flexion_l", "lean",
                                                 "fore_aft_angle") if c in m.columns}
    exported_mot = dict(angles)
    exported_mot.update({c: m[c].to_numpy(float) for c in ("speed", "com_x", "com_y", "com_z",
                                                          "fore_aft_distance")
                         if c in m.columns})
    fps = json.loads((folder / "summary.json").read_text())["fps"]
    t_round = 5e-7 + 1e-12                 # joints3d.csv's times: 6 decimals
    csv_round = lambda v: CSV_ROUNDING_M + 1e-12 * np.abs(v)            # noqa: E731
    c3d_round = lambda v: CSV_ROUNDING_M + 1.2e-7 * np.abs(v)           # noqa: E731, float32
    plan = [("angles.mot", folder / "angles.mot", MOT_CLIENTS,
             lambda r, p: check_columns(r, p, ref["time"], angles))]
    if "rotations" in ref:
        plan.append(("camera_rotations.mot", folder / "camera_rotations.mot", MOT_CLIENTS,
                     lambda r, p: check_columns(r, p, ref["time"], ref["rotations"], True)))
    plan += [
        ("joints3d.trc", folder / "joints3d.trc", TRC_CLIENTS,
         lambda r, p: check_points(r, p, ref["time"], ref["joints"], ref["joint_names"],
                                   csv_round, t_offset=1.0 / fps, t_tol=t_round)),
        ("joints3d.c3d", folder / "joints3d.c3d", C3D_CLIENTS,
         lambda r, p: check_points(r, p, ref["time"] - ref["time"][0], ref["joints"],
                                   ref["joint_names"], c3d_round, t_tol=t_round)),
        ("export .trc", exports / "joints.trc", TRC_CLIENTS,
         lambda r, p: check_points(r, p, ref["time"], ref["joints"], ref["joint_names"])),
        ("export .mot", exports / "metrics.mot", MOT_CLIENTS,
         lambda r, p: check_columns(r, p, ref["time"], exported_mot)),
        ("export .c3d", exports / "joints.c3d", C3D_CLIENTS,
         lambda r, p: check_points(r, p, ref["time"] - ref["time"][0], ref["joints"],
                                   ref["joint_names"], c3d_round, t_tol=t_round)),
        ("export .csv", exports / "joints.csv", CSV_CLIENTS,
         lambda r, p: check_points(r, p, ref["time"], ref["joints"], ref["joint_names"])),
    ]
    for what, path, clients, check in plan:
        if not path.is_file():                   # the gap copies hold only the tables
            continue
        for client, readers in clients.items():
            if client != "pandas" and not versions.get(client):
                rows.append((label, what, client, "-", "absent", np.nan, 0))
                continue
            for reader_name, reader in readers:
                try:
                    err, n = check(reader, path)
                    status = "ok" if err <= TOL else "DIFFERS"
                except Exception as exc:                      # the client refused the file
                    err, n = np.nan, 0
                    status = "ERROR " + str(exc).strip().splitlines()[-1][:90]
                    if "-v" in sys.argv:
                        traceback.print_exc()
                rows.append((label, what, client, reader_name, status, err, n))


def gap_folder(src: Path, dst: Path, seed=3) -> Path:
    """A copy of a mocap results folder with gaps (the harsh case)."""
    dst.mkdir(parents=True, exist_ok=True)
    for name in ("summary.json", "joints3d.csv", "metrics.csv"):
        shutil.copy(src / name, dst / name)
    rng = np.random.default_rng(seed)
    for name, frac, cols_of in (("joints3d.csv", 0.12, lambda c: c[2:]),
                                ("metrics.csv", 0.10, lambda c: [k for k in c if k in (
                                    "knee_flexion_r", "knee_flexion_l", "hip_flexion_r",
                                    "hip_flexion_l", "lean", "fore_aft_angle")])):
        lines = (dst / name).read_text().splitlines()
        comments = [ln for ln in lines if ln.startswith("#")]
        t = pd.read_csv(dst / name, comment="#", keep_default_na=False, na_values=[""],
                        dtype={"outside": str})
        cols = cols_of(list(t.columns))
        if name == "joints3d.csv":                      # whole joints, the last one included
            joints = [c[:-2] for c in cols if c.endswith("_X")]
            for j in joints:
                gone = rng.random(len(t)) < frac
                t.loc[gone, [f"{j}_X", f"{j}_Y", f"{j}_Z"]] = np.nan
            t.loc[len(t) // 2, [f"{joints[-1]}_{a}" for a in "XYZ"]] = np.nan
        else:
            for c in cols:
                t.loc[rng.random(len(t)) < frac, c] = np.nan
        (dst / name).write_text("\n".join(comments) + "\n" + t.to_csv(index=False))
    return dst


def export_all(folder: Path, to: Path) -> Path:
    to.mkdir(parents=True, exist_ok=True)
    for fmt, name in (("trc", "joints.trc"), ("c3d", "joints.c3d"), ("mot", "metrics.mot"),
                      ("csv", "joints.csv")):
        assert main(["export", fmt, str(folder), "--to", str(to / name), "--force", "-q"]) == 0
    return to


def rotations_vs_truth(folder: Path, prj: Path) -> str | None:
    """camera_rotations.mot (read back with photogram's read_mot) against the
    simulator's true rotations (truth_rotations of the project): median and
    largest |difference| of pan, tilt, roll over cameras and frames (deg)."""
    from photogram.io.trajectories import read_mot
    truth = prj.parent / "camera_frames.csv"
    if not (folder / "camera_rotations.mot").is_file() or not truth.is_file():
        return None
    mot = read_mot(folder / "camera_rotations.mot")
    t = pd.read_csv(truth, comment="#")
    frames = pd.read_csv(folder / "joints3d.csv", comment="#")["frame"].to_numpy(int)
    out = []
    for k, what in enumerate(("pan", "tilt", "roll")):
        d = []
        for c in dict.fromkeys(t["camera"]):
            rows = t[t["camera"] == c].set_index("frame").loc[frames]
            a = pan_tilt_roll(opk_to_matrix(np.radians(
                rows[["omega", "phi", "kappa"]].to_numpy(float))))
            d.append((mot[f"{c}_{what}"] - a[:, k] + 180) % 360 - 180)
        d = np.abs(np.concatenate(d))
        out.append(f"{what} median {np.median(d):.3f} max {np.max(d):.3f}")
    return "camera_rotations.mot vs the true rotations (deg): " + ", ".join(out)


def main_benchmark() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=None, help="work folder (default: temporary)")
    ap.add_argument("--reuse", action="store_true", help="reuse results already in --out")
    ap.add_argument("-v", action="store_true", help="tracebacks of refused files")
    ap.add_argument("--without", action="append", default=[],
                    choices=("opensim", "pose2sim", "ezc3d"),
                    help="leave a client out, as if absent (checks the nan/0 of RESULT)")
    args = ap.parse_args()
    out = args.out or Path(tempfile.mkdtemp(prefix="mocap-clients-"))
    versions = client_versions()
    versions.update({c: None for c in args.without})
    print("clients: " + ", ".join(f"{k} {v or 'absent'}" for k, v in versions.items())
          + f", pandas {pd.__version__}")
    rows, gaps = [], []
    for label, prj in PROJECTS.items():
        if "pose2sim" in label and not (prj.parent / "../../../shared/data/pose2sim-demo") \
                .resolve().is_dir():
            print(f"{label}: skipped (no /work/shared/data/pose2sim-demo)")
            continue
        folder = out / prj.stem
        if not (args.reuse and (folder / "summary.json").is_file()):
            assert main(["mocap", str(prj), "--output", str(folder), "-q"]) == 0, label
        run_checks(folder, export_all(folder, out / f"{prj.stem}-export"), versions, label,
                   rows)
        truth = rotations_vs_truth(folder, prj)
        if truth:
            print(f"{label}: {truth}")
        harsh = gap_folder(folder, out / f"{prj.stem}-gaps")
        run_checks(harsh, export_all(harsh, out / f"{prj.stem}-gaps-export"), versions,
                   label + " GAPS", gaps)
    fmt = "{:<30} {:<22} {:<9} {:<20} {:>10} {:>5}  {}"
    for title, table in (("normal", rows), ("harsh: gaps (only the exports: mocap's own files "
                                            "come from the gap-free run)", gaps)):
        print(f"\n{title}")
        print(fmt.format("results", "file", "client", "reader", "max err", "cols", "status"))
        for label, what, client, reader, status, err, n in table:
            print(fmt.format(label.replace(" GAPS", ""), what, client, reader,
                             f"{err:.1e}" if np.isfinite(err) else str(err), n, status))
    summary = []
    for client in ("opensim", "pose2sim", "ezc3d", "pandas"):
        mine = [r for r in rows if r[2] == client and r[4] != "absent"]
        ok = sum(r[4] == "ok" for r in mine)
        errs = [r[5] for r in mine if np.isfinite(r[5])]
        g = [r for r in gaps if r[2] == client and r[4] != "absent"]
        summary.append(f"{client}_files={len(mine)} {client}_ok={ok} "
                       f"{client}_max_err={max(errs) if errs else np.nan:.1e} "
                       f"{client}_gaps_ok={sum(r[4] == 'ok' for r in g)}/{len(g)}")
    print(f"\nwork folder: {out}")
    print("RESULT " + " ".join(f"{k}={v or 'nan'}" for k, v in versions.items()) + " "
          + " ".join(summary))


if __name__ == "__main__":
    main_benchmark()
