"""From videos to the stick model (issue 19): the simulated jump rendered
as three videos (photogram.simulation.jump_video; the normal set and the
harsh set the trackers were not tuned on), tracked by `photogram track`,
intersected by `photogram intersect` with the lab and field results of
`make demo`, and compared with the truth:

* markers: centre RMS (px) of the markers found, labels right / wrong /
  flagged (summary.json of the tracking);
* ski lines: the direction of the line through each tracked ski's points
  against the true ski axis in the image (degrees);
* stick model: per parameter (alpha, beta, gamma, delta_phi, phi, Z0, v)
  chi-square = sum over the exposures of ((estimate - truth) / sigma)^2
  with the sigmas `photogram intersect` propagates (image noise and the
  orientation's covariance), against its 99 % quantile for that many
  exposures; the truth is the stick model of the true points and skis
  (projects/jumps/truth);
* speed: camera frames per CPU-second of the whole tracking (one core
  takes 3 x 48 frames of 640x480: the issue's "frames/s per camera per
  core", the rate at which one core keeps up with one camera), and the
  synchronized frame sets (one frame of every camera) per CPU-second (reading the
  videos included) on this machine.

Run (after make demo): .venv/bin/python benchmarks/track_jump.py [--sets normal harsh]
"""

import argparse
import json
import shutil
import tempfile
import time
from pathlib import Path

import photogram  # noqa: F401  (single-threaded BLAS before numpy)
import numpy as np
import pandas as pd
from scipy.stats import chi2 as chi2_dist

from photogram.commands.intersect import intersect_and_write
from photogram.commands.track import track_and_write
from photogram.jump.stick import stick_model
from photogram.project import read_project
from photogram.simulation.jump_video import harsh_settings, render_jump_videos, write_jump_videos

ROOT = Path(__file__).resolve().parents[1]
JUMPS = ROOT / "projects" / "jumps"
PARAMETERS = ("alpha", "beta", "gamma", "delta_phi", "phi", "Z0", "v")


def truth_table(project):
    """The stick model of the true points and skis, in the units of
    exposures.csv (the project's)."""
    t = JUMPS / "truth"
    pts = pd.read_csv(t / "jumper_points.csv", comment="#", dtype={"exposure": str})
    sk = pd.read_csv(t / "skis.csv", comment="#", dtype={"exposure": str})
    ids = sorted(pts.exposure.unique())
    P = np.stack([pts[pts.exposure == e].set_index("point").loc[["P1", "P2", "P3", "P4"],
                                                                ["X", "Y", "Z"]].to_numpy()
                  for e in ids])
    tails, tips = [], []
    for e in ids:
        s = sk[sk.exposure == e].set_index("line").loc[["L1", "L2"]]
        tails.append(s[["X_tail", "Y_tail", "Z_tail"]].to_numpy())
        tips.append(s[["X_tip", "Y_tip", "Z_tip"]].to_numpy())
    tails, tips = np.array(tails), np.array(tips)
    d = tips - tails
    cfg = project.intersect
    model = stick_model(P, d[:, 0], d[:, 1], fps=cfg.fps, length_unit=project.units.length,
                        ski_length=cfg.ski_length, binding_fraction=cfg.binding_fraction,
                        c1=tails[:, 0], c2=tails[:, 1], forward="flight")
    return model.to_frame(angle_unit=project.units.angle, exposures=ids)


def chi_square(est: pd.DataFrame, true: pd.DataFrame) -> dict:
    """Per parameter: chi2, exposures used, the 99 % quantile, inside."""
    j = est.merge(true, on="exposure", suffixes=("", "_true"))
    out = {}
    for p in PARAMETERS:
        ok = np.isfinite(j[p]) & np.isfinite(j[f"sigma_{p}"]) & (j[f"sigma_{p}"] > 0)
        z = (j[p][ok] - j[f"{p}_true"][ok]) / j[f"sigma_{p}"][ok]
        n = int(ok.sum())
        c = float((z ** 2).sum())
        q = float(chi2_dist.ppf(0.99, n)) if n else float("nan")
        out[p] = {"chi2": c, "n": n, "q99": q, "inside": bool(n and c <= q),
                  "max_abs_z": float(np.abs(z).max()) if n else float("nan")}
    return out


def run_set(name, settings, work: Path):
    """Render, track and intersect one set in ``work``; returns the figures."""
    folder = work / name
    folder.mkdir()
    for f in ("track.prj", "jumps-video.prj"):
        text = (JUMPS / f).read_text().replace('"../', f'"{ROOT.as_posix()}/projects/')
        (folder / f).write_text(text)
    t = time.perf_counter()
    write_jump_videos(render_jump_videos(settings), folder / "video")
    render_s = time.perf_counter() - t
    track = read_project(folder / "track.prj")
    if name != "normal":           # the harsh set's sync lag: estimated, not given
        track.track.offsets = None
    t = time.perf_counter()
    cpu = time.process_time()
    _, run = track_and_write(track)
    track_s, track_cpu = time.perf_counter() - t, time.process_time() - cpu
    s = run.summary
    frames = sum(len(v) for v in run.frames.values())
    jp = read_project(folder / "jumps-video.prj")
    _, result = intersect_and_write(jp)
    est = pd.read_csv(folder / "results-video" / "exposures.csv", dtype={"exposure": str})
    chi = chi_square(est, truth_table(jp))
    return {"set": name, "render_s": render_s, "track_s": track_s,
            "fps_per_camera_core": frames / track_cpu,
            "sets_per_s": frames / len(run.frames) / track_cpu,
            "markers": s["truth"]["markers"], "skis": s["truth"].get("skis"),
            "offsets": s["offsets"], "offsets_right": s["truth"].get("offsets_right"),
            "found": f"{s['markers_found']}/{s['markers_expected']}",
            "ski_lines": f"{s['ski_lines_found']}/{s['ski_lines_expected']}",
            "stick_exposures": int(np.isfinite(est.alpha).sum()), "chi2": chi,
            "sigma0": result.summary["sigma0"]}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sets", nargs="+", default=["normal", "harsh"])
    ap.add_argument("--keep", type=Path, help="keep the rendered sets and results here")
    a = ap.parse_args(argv)
    from photogram.simulation.jump_video import VideoSettings
    settings = {"normal": VideoSettings(), "harsh": harsh_settings()}
    work = Path(tempfile.mkdtemp(prefix="track-jump-"))
    results = []
    try:
        for name in a.sets:
            r = run_set(name, settings[name], work)
            results.append(r)
            m, k = r["markers"], r["skis"] or {}
            inside = sum(v["inside"] for v in r["chi2"].values())
            print(f"{name}: markers {r['found']} found, centre RMS {m['rms_px']:.3f} px "
                  f"(max {m['max_px']:.3f}), {m['n_wrong']} wrong labels, "
                  f"{m['right_or_flagged']:.1%} right or flagged; ski lines {r['ski_lines']}, "
                  f"direction RMS {k.get('rms_deg', float('nan')):.3f} deg (median "
                  f"{k.get('median_deg', float('nan')):.3f}, max {k.get('max_deg', float('nan')):.2f}), "
                  f"{k.get('n_wrong_label', 0)} wrong ski labels; offsets {r['offsets']} "
                  f"(right: {r['offsets_right']}); stick model at {r['stick_exposures']} of 24 "
                  f"exposures, sigma0 {r['sigma0']:.3f}, chi-square inside the 99 % band for "
                  f"{inside} of {len(PARAMETERS)} parameters; "
                  f"{r['fps_per_camera_core']:.1f} frames/s per camera per core "
                  f"({r['sets_per_s']:.1f} synchronized frame sets/s)")
            for p, v in r["chi2"].items():
                print(f"    {p:10s} chi2 {v['chi2']:9.1f}  n {v['n']:2d}  q99 {v['q99']:6.1f}  "
                      f"{'inside' if v['inside'] else 'OUTSIDE'}  max|z| {v['max_abs_z']:.2f}")
        if a.keep:
            shutil.copytree(work, a.keep, dirs_exist_ok=True)
    finally:
        shutil.rmtree(work, ignore_errors=True)
    by = {r["set"]: r for r in results}
    parts = []
    for name, r in by.items():
        m, k = r["markers"], r["skis"] or {}
        parts += [f"{name}_marker_rms_px={m['rms_px']:.3f}", f"{name}_wrong_labels={m['n_wrong']}",
                  f"{name}_right_or_flagged={m['right_or_flagged']:.3f}",
                  f"{name}_ski_deg_rms={k.get('rms_deg', float('nan')):.3f}",
                  f"{name}_stick_exposures={r['stick_exposures']}",
                  f"{name}_chi2_inside={sum(v['inside'] for v in r['chi2'].values())}/7",
                  f"{name}_fps={r['fps_per_camera_core']:.1f}",
                  f"{name}_sets_per_s={r['sets_per_s']:.1f}"]
    print("RESULT " + " ".join(parts))
    return json.dumps(results, default=str)


if __name__ == "__main__":
    main()
