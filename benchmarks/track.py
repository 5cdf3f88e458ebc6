"""Marker tracking (photogram.track, issue 19): speed and accuracy on a
rendered jump folder (S1.avi S2.avi S3.avi, seeds.csv, frames.csv,
truth/markers.csv, as photogram.simulation.jump_video writes them).

Speed: frames per second per camera per core: the frames of all cameras
divided by the CPU time (process time, one OpenCV thread, single-threaded
BLAS) of :func:`photogram.track.tracks.track_markers`: background, marker
candidates of every frame, 2D tracks, sync offsets (estimated unless
``--given-offsets``), 3D checks, the table. Decoding the videos is timed
apart (it depends on the codec, not on the tracker).

Accuracy against truth/markers.csv: RMS of the centres of the rows with
status ok; a *wrong* row is an ok row more than ``--wrong`` px (default 1)
from its marker's true position or whose marker is hidden in the truth;
flagged rows are counted per status. With ``--perturb S`` the cameras are
the true ones with their angles disturbed by N(0, S gon) and positions by
N(0, S dm) (an estimated orientation); default 0: the true views. With
``--cameras RESULTS`` the orientation a field bundle estimated
(``photogram orient projects/field/field.prj``: stations.csv, cameras.toml
of its results folder; ``make demo`` writes one).

Run: .venv/bin/python benchmarks/track.py [/work/jumpvideo/normal] [--repeat 2]
"""

import argparse
import time
from pathlib import Path

import photogram  # noqa: F401  (single-threaded BLAS before numpy)
import cv2
import numpy as np
import pandas as pd

from photogram.lines.views import ViewCamera
from photogram.simulation.ski_lines import field_cameras
from photogram.track.tracks import track_markers
from photogram.track.tracks2d import TrackSettings
from photogram.track.video import read_videos

MARKERS = ["P1", "P2", "P3", "P4"]
# the rendered videos are in the project's pixel frame (photogram.simulation.jump_video:
# the top-left corner of the image at (0, 0)), as photogram track's default
PIXEL_OFFSET = 0.5


def load(folder: Path):
    paths = {}
    for s in ("S1", "S2", "S3"):
        p = folder / f"{s}.avi"
        paths[s] = p if p.exists() else folder / s
    c0 = time.process_time()
    frames, fps = read_videos(paths)
    decode = time.process_time() - c0
    seeds = pd.read_csv(folder / "seeds.csv", dtype={"station": str, "marker": str})
    expo = pd.read_csv(folder / "frames.csv", dtype={"exposure": str})
    truth = pd.read_csv(folder / "truth" / "markers.csv", dtype={"exposure": str})
    offsets = None
    if (folder / "truth" / "offsets.csv").exists():
        o = pd.read_csv(folder / "truth" / "offsets.csv")
        offsets = dict(zip(o.station, o.offset.astype(int)))
    return frames, fps, seeds, expo, truth, offsets, decode


def cameras(perturb: float, seed: int = 5):
    cams = field_cameras()
    if perturb <= 0:
        return cams
    from photogram.geometry import matrix_to_opk
    rng = np.random.default_rng(seed)
    out = {}
    for n, c in cams.items():
        ang = matrix_to_opk(c.R) + rng.normal(0, perturb * np.pi / 200, 3)
        out[n] = ViewCamera.from_angles(ang, c.X0 + rng.normal(0, perturb, 3), c.io,
                                        c.model, n)
    return out


def estimated_cameras(results: Path):
    """The orientation a field bundle estimated (``photogram orient
    projects/field/field.prj``: stations.csv in gon and dm, cameras.toml)."""
    import tomllib
    from photogram.geometry import camera_model
    st = pd.read_csv(results / "stations.csv")
    cams = tomllib.loads((results / "cameras.toml").read_text())["cameras"]
    out = {}
    for r in st.itertuples():
        c = cams[r.camera]
        names = camera_model(c["model"]).parameter_names
        io = [c[p]["value"] for p in names]
        ang = np.array([r.omega, r.phi, r.kappa]) * np.pi / 200
        out[r.station] = ViewCamera.from_angles(ang, [r.X0, r.Y0, r.Z0], io, c["model"],
                                                r.station)
    return out


def evaluate(table: pd.DataFrame, truth: pd.DataFrame, wrong_px: float):
    t = truth.set_index(["exposure", "station", "marker"])
    m = table.join(t[["x", "y", "visible"]], on=["exposure", "station", "marker"],
                   rsuffix="_true")
    ok = m[m.status == "ok"]
    err = np.hypot(ok.x - ok.x_true, ok.y - ok.y_true)
    vis = ok.visible.astype(str).str.lower() == "true"
    wrong = (err > wrong_px) | ~vis
    good = ok[~wrong]
    rms = float(np.sqrt(np.mean(np.square(err[~wrong])))) if len(good) else float("nan")
    z = (err[~wrong] / ok.sigma[~wrong]).to_numpy()
    return {"rows": len(m), "ok": len(ok), "wrong": int(wrong.sum()),
            "lost": int((m.status == "lost").sum()),
            "ambiguous": int((m.status == "ambiguous").sum()),
            "rms": rms, "rms_sigma": float(np.sqrt(np.mean(ok.sigma[~wrong] ** 2))),
            "z_rms": float(np.sqrt(np.mean(z ** 2 / 2))) if len(z) else float("nan"),
            "visible_flagged": int(((m.status != "ok")
                                    & (m.visible.astype(str).str.lower() == "true")).sum()),
            "wrong_rows": ok[wrong]}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("folder", nargs="?", default="/work/jumpvideo/normal")
    ap.add_argument("--repeat", type=int, default=1)
    ap.add_argument("--perturb", type=float, default=0.0)
    ap.add_argument("--cameras", default="true",
                    help="true, or a results folder of the field bundle (stations.csv, "
                         "cameras.toml) for an estimated orientation")
    ap.add_argument("--given-offsets", action="store_true")
    ap.add_argument("--wrong", type=float, default=1.0)
    args = ap.parse_args()
    cv2.setNumThreads(1)
    folder = Path(args.folder)
    frames, fps, seeds, expo, truth, true_off, decode = load(folder)
    cams = cameras(args.perturb) if args.cameras == "true" \
        else estimated_cameras(Path(args.cameras))
    n_frames = sum(len(f) for f in frames.values())
    best = np.inf
    for _ in range(args.repeat):
        c0, w0 = time.process_time(), time.perf_counter()
        res = track_markers(frames, cams, seeds, MARKERS, expo,
                            offsets=true_off if args.given_offsets else None,
                            settings=TrackSettings(pixel_offset=PIXEL_OFFSET))
        cpu, wall = time.process_time() - c0, time.perf_counter() - w0
        best = min(best, cpu)
    ev = evaluate(res.table, truth, args.wrong)
    fps_core = n_frames / best          # camera frames per CPU second
    print(f"{folder}: {len(frames)} cameras x {n_frames // len(frames)} frames, "
          f"{fps:g} fps; decode {decode:.2f} s CPU")
    print(f"tracking: CPU {best:.2f} s (wall {wall:.2f} s): {fps_core:.1f} frames/s per "
          f"camera per core ({n_frames} camera frames / CPU s; "
          f"{n_frames / len(frames) / best:.1f} synchronized {len(frames)}-camera frame sets/s)")
    if res.sync is not None:
        print("sync offsets estimated:\n" + res.sync.summary())
    print(f"offsets used {res.offsets}, truth {true_off}")
    print(f"rows {ev['rows']}: ok {ev['ok']} (wrong {ev['wrong']}), lost {ev['lost']}, "
          f"ambiguous {ev['ambiguous']}; visible in the truth but flagged "
          f"{ev['visible_flagged']}")
    print(f"centre RMS {ev['rms']:.3f} px (RMS of the given sigmas {ev['rms_sigma']:.3f} px, "
          f"error/sigma RMS per coordinate {ev['z_rms']:.2f})")
    flagged = res.table[res.table.status != "ok"]
    print("flags per station and marker:")
    print(flagged.groupby(["station", "marker", "status"]).size().to_string())
    print("reasons:")
    print(flagged.reason.str.replace(r"[0-9.]+", "#", regex=True).value_counts()
          .head(12).to_string())
    if ev["wrong"]:
        print("WRONG rows:")
        print(ev["wrong_rows"].to_string())
    print(f"RESULT fps_per_camera_core={fps_core:.1f} rms_px={ev['rms']:.3f} ok={ev['ok']} "
          f"wrong={ev['wrong']} lost={ev['lost']} ambiguous={ev['ambiguous']} "
          f"rows={ev['rows']} offsets_right={res.offsets == true_off if true_off else 'n/a'}")


if __name__ == "__main__":
    main()
