"""Ski lines tracked in the rendered jump videos (issue 19, item 4):
accuracy of photogram.track.skis.track_skis against the truth.

Reads a data folder written by photogram.simulation.jump_video
(``S1.avi S2.avi S3.avi``, ``frames.csv``, ``truth/markers.csv``,
``truth/skis.csv``, ``truth/offsets.csv``; see its README.txt). The marker
input is the TRUE marker positions plus N(0, 0.2 px) (status "lost" where
not visible) until the marker tracker (photogram.track.tracks) is there;
the cameras are the true views (field_cameras); the background is the
median of the frames without the jumper.

Per exposure and station and ski: the angle between the principal axis of
the sampled points and the true axis (deg), and the distances of the
points from the true axis (px); then RMS and max per station and over all,
the flags, the label check, and the time per image; the 3D ski directions
intersected from the tracked points (true cameras) against the truth. For
comparison the
same figures for OpenCV's line-segment detector (LSD) in the same bands
(the edge segments near each found axis, their middle line).

Run: .venv/bin/python benchmarks/track_skis.py [FOLDER] [--sync truth|none]
     FOLDER defaults to /work/jumpvideo/normal; --sync truth uses the
     true frame offsets (truth/offsets.csv), none the nominal frames only.
"""

import argparse
import sys
import time
from pathlib import Path

import photogram  # noqa: F401  (single-threaded BLAS before numpy)
import cv2
import numpy as np
import pandas as pd

from photogram.simulation.ski_lines import field_cameras
from photogram.track.skis import track_skis


def read_avi(path):
    cap = cv2.VideoCapture(str(path), cv2.CAP_OPENCV_MJPEG)
    out = []
    while True:
        ok, f = cap.read()
        if not ok:
            break
        out.append(f[..., 0] if f.ndim == 3 else f)
    cap.release()
    return np.array(out)


def load(folder, sync):
    folder = Path(folder)
    stations = sorted(p.stem for p in folder.glob("S*.avi"))
    frames = {st: read_avi(folder / f"{st}.avi") for st in stations}
    fr = pd.read_csv(folder / "frames.csv", dtype={"exposure": str})
    offs = pd.read_csv(folder / "truth" / "offsets.csv").set_index("station")["offset"]
    # a video starting d frames late shows exposure e at frame (nominal - d)
    offsets = {st: -int(offs.get(st, 0)) for st in stations} if sync == "truth" else None
    tm = pd.read_csv(folder / "truth" / "markers.csv", dtype={"exposure": str})
    ts = pd.read_csv(folder / "truth" / "skis.csv", dtype={"exposure": str})
    rng = np.random.default_rng(7)
    markers = pd.DataFrame({
        "exposure": tm.exposure, "station": tm.station, "marker": tm.marker,
        "x": tm.x + rng.normal(0, 0.2, len(tm)), "y": tm.y + rng.normal(0, 0.2, len(tm)),
        "sigma": 0.2, "status": np.where(tm.visible, "ok", "lost"), "reason": ""})
    ef = fr.sort_values("exposure")["frame"].to_numpy()
    backgrounds = {}
    for st, F in frames.items():
        used = ef + (offsets or {}).get(st, 0)
        lead = np.setdiff1d(np.arange(len(F)), used)
        backgrounds[st] = np.median(F[lead], axis=0).astype(float)
    return frames, backgrounds, markers, ef, offsets, ts


def errors(table, truth):
    rows = []
    t = truth.set_index(["exposure", "station", "ski"])
    for (e, st, lab), g in table.groupby(["exposure", "station", "line"]):
        r = t.loc[(e, st, lab)]
        a = np.array([r.x_tail, r.y_tail])
        b = np.array([r.x_tip, r.y_tip])
        u = (b - a) / np.linalg.norm(b - a)
        n = np.array([-u[1], u[0]])
        xy = g[["x", "y"]].to_numpy()
        c = xy - xy.mean(0)
        d = np.linalg.eigh(c.T @ c)[1][:, -1]
        d = d if d @ u > 0 else -d
        ang = np.degrees(np.arctan2(u[0] * d[1] - u[1] * d[0], u @ d))
        dist = (xy - a) @ n
        o = t.loc[(e, st, "L2" if lab == "L1" else "L1")]
        a2, b2 = np.array([o.x_tail, o.y_tail]), np.array([o.x_tip, o.y_tip])
        u2 = (b2 - a2) / np.linalg.norm(b2 - a2)
        dist2 = (xy - a2) @ np.array([-u2[1], u2[0]])
        rows.append((e, st, lab, ang, np.sqrt(np.mean(dist ** 2)), np.abs(dist).max(),
                     np.sqrt(np.mean(dist2 ** 2)), bool((xy[-1] - xy[0]) @ u > 0)))
    return pd.DataFrame(rows, columns=["exposure", "station", "line", "angle_deg", "dist_rms",
                                       "dist_max", "dist_other", "tail_to_tip"])


def lsd_table(frames, ef, offsets, result, *, band=2.0, max_turn_deg=3.0, min_length=4.0):
    """The alternative detector, for comparison: OpenCV's line-segment
    detector (LSD) on each frame; per ski the segments (edges) within
    ``band`` px and ``max_turn_deg`` of the axis that track_skis found (the
    band prediction), their length-weighted total least-squares line (the
    middle of the two edges) sampled over the same span as track_skis'
    points. Same format as ``result.table``."""
    lsd = cv2.createLineSegmentDetector()
    rows = []
    tab = result.table.groupby(["exposure", "station", "line"])
    names = {e: i for i, e in enumerate(sorted(set(result.checks.exposure)))}
    for (e, st, lab), g in tab:
        line = result.lines[(e, st)][lab]
        fi = int(ef[names[e]] + (offsets or {}).get(st, 0))
        segs = lsd.detect(frames[st][fi])[0]
        if segs is None:
            continue
        segs = segs.reshape(-1, 2, 2).astype(float)
        v = segs[:, 1] - segs[:, 0]
        L = np.linalg.norm(v, axis=1)
        cosang = np.abs(v @ line.direction) / np.maximum(L, 1e-9)
        mid = segs.mean(1)
        keep = ((L >= min_length) & (cosang > np.cos(np.radians(max_turn_deg)))
                & (np.abs(line.distance(mid)) <= band))
        t_mid = (mid - line.point) @ line.direction
        keep &= (t_mid > line.ends[0]) & (t_mid < line.ends[1])
        if keep.sum() < 2:
            continue
        pts = np.concatenate([s0 + np.linspace(0, 1, max(int(l), 2))[:, None] * (s1 - s0)
                              for (s0, s1), l in zip(segs[keep], L[keep])])
        c = pts.mean(0)
        d = np.linalg.eigh((pts - c).T @ (pts - c))[1][:, -1]
        d = d if d @ line.direction > 0 else -d
        xy = g[["x", "y"]].to_numpy()
        t = (xy - c) @ d
        for x, y in c + t[:, None] * d:
            rows.append((e, st, lab, x, y))
    return pd.DataFrame(rows, columns=["exposure", "station", "line", "x", "y"])


def space_errors(table, cameras):
    """3D ski directions intersected from the tracked points (fit_view_line,
    eq. (C11), then intersect_line) against the true ones of jump_truth:
    angle (deg) per exposure and ski, where the ski is in >= 2 views."""
    from photogram.errors import GeometryError
    from photogram.lines.space_line import intersect_line
    from photogram.lines.views import fit_view_line
    from photogram.simulation.jump import jump_truth
    T = jump_truth()
    out = []
    exposures = sorted(table.exposure.unique())
    for (e, lab), g in table.groupby(["exposure", "line"]):
        lines = {st: fit_view_line(h[["x", "y"]].to_numpy(), cameras[st],
                                   h.sigma.to_numpy(), label=lab)
                 for st, h in g.groupby("station")}
        if len(lines) < 2:
            continue
        try:
            X = intersect_line(lines, cameras, label=lab)
        except GeometryError:
            continue
        k = 0 if lab == "L1" else 1
        i = exposures.index(e) if len(exposures) != 24 else int(e) - 1
        d = T["ski_tip"][i, k] - T["ski_tail"][i, k]
        c = abs(X.line.direction @ d) / np.linalg.norm(d)
        out.append((e, lab, len(lines), np.degrees(np.arccos(min(c, 1.0)))))
    return pd.DataFrame(out, columns=["exposure", "line", "views", "angle_deg"])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("folder", nargs="?", default="/work/jumpvideo/normal")
    ap.add_argument("--sync", choices=("truth", "none"), default="truth")
    args = ap.parse_args()
    if not (Path(args.folder) / "frames.csv").exists():
        print(f"no data in {args.folder}")
        print("RESULT status=skipped")
        return 0
    frames, bgs, markers, ef, offsets, truth = load(args.folder, args.sync)
    cams = field_cameras()
    t0 = time.perf_counter()
    res = track_skis(frames, bgs, cams, markers, ef, offsets=offsets)
    dt = time.perf_counter() - t0
    n_img = len(ef) * len(frames)
    err = errors(res.table, truth)
    pd.set_option("display.width", 200)
    print(f"{args.folder} (sync {args.sync}): {len(err)} of {2 * n_img} ski images measured, "
          f"{len(res.flags)} flagged")
    print("\ndirection error (deg) per exposure, station, ski:")
    print(err.pivot_table(index="exposure", columns=["station", "line"],
                          values="angle_deg").round(3).to_string())

    def rms(x):
        return float(np.sqrt(np.mean(np.square(x))))

    per = err.groupby("station").agg(
        dir_rms=("angle_deg", rms), dir_max=("angle_deg", lambda x: x.abs().max()),
        dist_rms=("dist_rms", rms), dist_max=("dist_max", "max"), n=("angle_deg", "size"))
    print("\nper station:")
    print(per.round(3).to_string())
    if len(res.flags):
        print("\nflags:")
        print(res.flags.to_string(index=False))
    print("\nlabel checks:", res.checks.status.value_counts().to_dict(),
          "swapped:", [f"{e}:{s}" for e, s in zip(res.checks.exposure, res.checks.swapped) if s])
    wrong = int((err.dist_rms > err.dist_other).sum())
    within = float((err.angle_deg.abs() < 0.1).mean())
    result = {
        "set": Path(args.folder).name, "sync": args.sync,
        "dir_rms_deg": f"{rms(err.angle_deg):.3f}",
        "dir_max_deg": f"{err.angle_deg.abs().max():.3f}",
        "within_0.1deg": f"{within:.2f}",
        "dist_rms_px": f"{rms(err.dist_rms):.3f}", "dist_max_px": f"{err.dist_max.max():.3f}",
        "found": len(err), "flagged": len(res.flags), "label_closer_to_other": wrong,
        "checks_ok": int((res.checks.status != "flagged").sum()),
        "s_per_image": f"{dt / n_img:.3f}",
        "s_per_frame": f"{dt / len(ef):.3f}",
    }
    # 3D: the skis intersected from the tracked points
    serr = space_errors(res.table, cams)
    print(f"\n3D ski directions from the tracked points ({len(serr)} skis, true cameras): "
          f"RMS {rms(serr.angle_deg):.3f} deg, max {serr.angle_deg.max():.3f} "
          f"(3 views: RMS {rms(serr.angle_deg[serr.views == 3]):.3f})")
    result["dir3d_rms_deg"] = f"{rms(serr.angle_deg):.3f}"
    result["dir3d_max_deg"] = f"{serr.angle_deg.max():.3f}"
    # the alternative: line segments (LSD) in the same bands
    lerr = errors(lsd_table(frames, ef, offsets, res), truth)
    print(f"\nLSD edges in the same bands ({len(lerr)} skis): direction RMS "
          f"{rms(lerr.angle_deg):.3f} deg, max {lerr.angle_deg.abs().max():.3f}; points "
          f"{rms(lerr.dist_rms):.3f} px RMS from the true axis")
    result["lsd_dir_rms_deg"] = f"{rms(lerr.angle_deg):.3f}"
    result["lsd_dist_rms_px"] = f"{rms(lerr.dist_rms):.3f}"
    print("RESULT " + " ".join(f"{k}={v}" for k, v in result.items()))
    return 0


if __name__ == "__main__":
    sys.exit(main())
