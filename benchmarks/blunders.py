"""Gross errors: blunders injected into real (CAMCAL) and simulated (field)
image observations, found by iterative data snooping and by robust
estimation (issue 12, item 2).

For every network, contamination rate (1, 3, 5 % of the image points) and
seed: blunders of uniform magnitude 5-50 sigma (sigma = the observation's
a-priori sigma) in a uniformly random image direction are added to randomly
chosen image points, starting from the same approximate values as the clean
adjustment. Then

* snooping: iterative data snooping (``photogram.stats.reliability.data_snooping``)
  at ``--alpha`` (two-sided normal quantile per coordinate), with the
  variance factor of the current adjustment (``scale="aposteriori"``:
  CAMCAL's a-priori 0.1 px is 1.6 times too small), several rejections per
  round (``per_round="point"``) and a final readmission test;
* robust: IRLS (``--loss``, tuning constant in units of a MAD scale, Huber
  warm start), flagging of the residuals beyond the same critical value,
  least-squares readjustment without them and readmission
  (``photogram.stats.robust.robust_cleaning``).

Reported per network and rate: detection rate (all blunders, >= 10 sigma,
5-10 sigma), the false-alarm rate (rejected clean image points / clean image
points, counting only rejections the same method does not make on the clean
data: CAMCAL has real small blunders of its own) against the per-point
rate 1 - (1 - alpha)^2 of two coordinate tests, and the largest change of
the cleaned result against the same method on the clean data, in units of
the clean least-squares sigmas (CAMCAL: interior parameters and object
points; field: station positions and angles, points); "LS" is the plain
least-squares result with the blunders, for comparison.

Run: .venv/bin/python benchmarks/blunders.py [--seeds 2] [--field-seeds 10]
CAMCAL needs ../shared/data/dbat/camcal beside the repository.
"""

from __future__ import annotations

import argparse
import copy
import time
from pathlib import Path

import photogram  # noqa: F401  (single-threaded BLAS before numpy)
import numpy as np

from photogram.adjust.build import build_problem
from photogram.adjust.solver import SolverOptions, solve
from photogram.geometry import matrix_to_opk
from photogram.stats.covariance import (
    camera_covariances, cofactors, point_covariances, station_covariances)
from photogram.stats.reliability import data_snooping
from photogram.stats.robust import robust_cleaning

ROOT = Path(__file__).resolve().parents[1]
CAMCAL_DATA = ROOT.parent / "shared" / "data" / "dbat" / "camcal"
RATES = (0.01, 0.03, 0.05)


# ----------------------------------------------------------------- networks

def load_network(name):
    """(base problem with approximate values, solver options, label)."""
    from photogram.bundle import approximate_if_needed
    from photogram.project import read_project
    if name == "camcal":
        prj = read_project(ROOT / "projects" / "camcal" / "camcal.prj")
        fix_interior = False
    elif name == "field":
        prj = _field_project()
        fix_interior = True                     # photogram orient
    else:
        raise ValueError(name)
    prj = approximate_if_needed(prj, {})
    adj = prj.adjustment
    opts = SolverOptions(max_iterations=adj.max_iterations, tolerance=adj.tolerance,
                         damping=adj.damping)
    base = build_problem(prj, fix_interior=fix_interior).problem
    pre = []
    if name == "camcal":
        # DBAT's data have real blunders of their own: take out what classical
        # snooping (one rejection per round) rejects on them, so that the
        # clean reference is clean at alpha and new rejections are false alarms
        q = copy.deepcopy(base)
        solve(q, opts)
        r = data_snooping(q, 0.001, options=opts, scale="aposteriori", per_round="one", readmit=True)
        base.active = [a.copy() for a in q.active]
        pre = r.rejected
    return base, opts, pre


def _field_project():
    from photogram.project import read_project
    try:
        return read_project(ROOT / "projects" / "field" / "field.prj")
    except Exception:   # the lab calibration has not run: the nominal cameras
        import shutil
        import tempfile
        tmp = Path(tempfile.mkdtemp()) / "field"
        shutil.copytree(ROOT / "projects" / "field", tmp, ignore=shutil.ignore_patterns("results"))
        text = (tmp / "field.prj").read_text().replace('"../lab/results/cameras.toml"',
                                                        '"cameras-nominal.toml"')
        (tmp / "field.prj").write_text(text)
        return read_project(tmp / "field.prj")


def image_records(problem):
    """The active image-point records as (block, row) pairs."""
    return [(k, int(i)) for k, b in enumerate(problem.blocks) if b.name == "image points"
            for i in np.flatnonzero(problem.active[k])]


# ----------------------------------------------------------------- results

def parameters(problem):
    """Estimated values by group: interior (free), station positions and
    angles, points (all)."""
    st, lay = problem.state, problem.layout
    io = np.concatenate([st.io[k][lay.free[c]] for k, c in enumerate(lay.camera_cols)]) \
        if lay.camera_cols else np.zeros(0)
    return {"interior": io, "positions": st.X0.ravel().copy(),
            "angles": matrix_to_opk(st.R).ravel().copy(), "points": st.points.ravel().copy()}


def sigmas(problem):
    """A-posteriori sigmas of :func:`parameters` (0 = fixed)."""
    cof = cofactors(problem)
    rs, _ = problem.evaluate(problem.state, jacobians=False)
    s0sq = sum(float(np.sum(r * r)) for r in rs) / problem.redundancy()
    lay = problem.layout
    cams = camera_covariances(cof, s0sq)
    io = np.concatenate([np.sqrt(np.diag(c))[lay.free[cc]] for c, cc in zip(cams, lay.camera_cols)]) \
        if cams else np.zeros(0)
    S = station_covariances(cof, problem.state.R, s0sq)
    sd = np.sqrt(np.clip(np.diagonal(S, axis1=1, axis2=2), 0, None))
    P = point_covariances(cof, s0sq)
    sp = np.sqrt(np.clip(np.diagonal(P, axis1=1, axis2=2), 0, None))
    return {"interior": io, "positions": sd[:, :3].ravel(), "angles": sd[:, 3:].ravel(),
            "points": sp.ravel()}


def shift(a, b, sig, groups):
    """max |a - b| / sigma over the free parameters of ``groups``."""
    out = 0.0
    for g in groups:
        d = a[g] - b[g]
        if g == "angles":
            d = (d + np.pi) % (2 * np.pi) - np.pi
        m = sig[g] > 0
        if m.any():
            out = max(out, float(np.max(np.abs(d[m]) / sig[g][m])))
    return out


def run_methods(base, opts, alpha, loss, per_round):
    """LS, snooping and robust on a copy of ``base``: (params, flagged sets, seconds)."""
    out = {}
    p = copy.deepcopy(base)
    t = time.perf_counter()
    solve(p, opts)
    out["ls"] = (parameters(p), set(), time.perf_counter() - t)
    q = copy.deepcopy(p)
    t = time.perf_counter()
    r = data_snooping(q, alpha, options=opts, scale="aposteriori", per_round=per_round, readmit=True,
                      swap_rays=4, max_rejections=len(image_records(q)) // 4)
    out["snooping"] = (parameters(q), _rows(q, r.rejected), time.perf_counter() - t + out["ls"][2])
    masks = {"snooping": [a.copy() for a in q.active]}
    q = copy.deepcopy(p)
    t = time.perf_counter()
    c = robust_cleaning(q, loss, alpha, options=opts)
    out["robust"] = (parameters(q), _rows(q, c.flagged), time.perf_counter() - t + out["ls"][2])
    masks["robust"] = [a.copy() for a in q.active]
    return out, p, masks


def same_removed(clean_base, masks, opts):
    """The clean data adjusted without the observations a method removed:
    the best that method could have done (the information of the removed
    observations is lost either way)."""
    out = {}
    for m, mask in masks.items():
        p = copy.deepcopy(clean_base)
        p.active = [a.copy() for a in mask]
        solve(p, opts)
        out[m] = parameters(p)
    return out


def _rows(problem, items):
    """(block index, row) of rejected records."""
    return {(r["k"], r["row"]) for r in items}


def inject(base, rate, rng):
    """A copy of ``base`` with blunders: {(block, row): magnitude in sigma}."""
    p = copy.deepcopy(base)
    recs = image_records(p)
    n = max(1, int(round(rate * len(recs))))
    pick = rng.choice(len(recs), n, replace=False)
    blunders = {}
    for j in pick:
        k, i = recs[j]
        m = rng.uniform(5.0, 50.0)
        a = rng.uniform(0.0, 2 * np.pi)
        blk = p.blocks[k]
        blk.xy[i] += m * blk.sigma[i, 0] * np.array([np.cos(a), np.sin(a)])
        blunders[(k, i)] = m
    return p, blunders


# ----------------------------------------------------------------- benchmark

def benchmark(name, seeds, alpha, loss, per_round):
    base, opts, pre = load_network(name)
    if pre:
        print(f"{name}: {len(pre)} image points of the original data rejected beforehand "
              f"(classical snooping, alpha 0.001, a-posteriori variance factor)")
    groups = ("interior", "points") if name == "camcal" else ("positions", "angles", "points")
    clean, p_clean, _ = run_methods(base, opts, alpha, loss, per_round)
    sig = sigmas(p_clean)
    n_rec = len(image_records(base))
    rows = []
    for rate in RATES:
        agg = {m: {"found": [], "false": 0, "clean": 0, "shift": [], "ideal": [], "t": []}
               for m in ("ls", "snooping", "robust")}
        for seed in range(seeds):
            rng = np.random.default_rng(1000 * seed + int(rate * 1000) + (7 if name == "field" else 0))
            p, blunders = inject(base, rate, rng)
            res, _, masks = run_methods(p, opts, alpha, loss, per_round)
            ideal = same_removed(base, masks, opts)
            for m, (par, flagged, secs) in res.items():
                a = agg[m]
                own = clean[m][1]
                a["found"] += [(mag, key in flagged) for key, mag in blunders.items()]
                new_false = flagged - set(blunders) - own
                a["false"] += len(new_false)
                a["clean"] += n_rec - len(blunders)
                a["shift"].append(shift(par, clean[m][0], sig, groups))
                a["ideal"].append(shift(par, ideal[m], sig, groups) if m in ideal else np.nan)
                a["t"].append(secs)
        for m, a in agg.items():
            f = np.array(a["found"], dtype=float)
            big = f[:, 0] >= 10
            small = ~big
            rows.append({
                "network": name, "rate": rate, "method": m, "n_obs": n_rec,
                "blunders": len(f), "det": f[:, 1].mean() if m != "ls" else np.nan,
                "det10": f[big, 1].mean() if big.any() and m != "ls" else np.nan,
                "det5_10": f[small, 1].mean() if small.any() and m != "ls" else np.nan,
                "missed10": [round(float(x), 1) for x in f[big & (f[:, 1] == 0), 0]] if m != "ls" else [],
                "false": a["false"] / a["clean"] if m != "ls" else np.nan,
                "shift_max": max(a["shift"]), "shift_med": float(np.median(a["shift"])),
                "ideal_max": max(a["ideal"]),
                "t": float(np.median(a["t"])), "own": len(clean[m][1])})
    return rows


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=2, help="seeds per rate for CAMCAL")
    ap.add_argument("--field-seeds", type=int, default=10, help="seeds per rate for the field network")
    ap.add_argument("--alpha", type=float, default=0.001)
    ap.add_argument("--loss", default="huber", choices=("huber", "cauchy", "soft_l1", "tukey"))
    ap.add_argument("--per-round", default="point", choices=("one", "point"))
    ap.add_argument("--networks", default="camcal,field")
    args = ap.parse_args()
    t0 = time.perf_counter()
    rows = []
    for name in args.networks.split(","):
        if name == "camcal" and not CAMCAL_DATA.is_dir():
            print(f"CAMCAL data not found at {CAMCAL_DATA}: skipped")
            continue
        rows += benchmark(name, args.seeds if name == "camcal" else args.field_seeds,
                          args.alpha, args.loss, args.per_round)
    pfa = 1 - (1 - args.alpha) ** 2
    print(f"alpha {args.alpha:g} per coordinate: expected false alarms per image point "
          f"{pfa:.4f}; robust loss {args.loss}; snooping per_round {args.per_round}")
    print(f"{'network':<7} {'rate':>4} {'method':<8} {'obs':>5} {'bl':>4} {'det':>6} {'det>=10':>7} "
          f"{'det5-10':>7} {'false':>7} {'f/exp':>5} {'own':>4} {'shift max':>9} {'median':>6} "
          f"{'vs same-removed':>15} {'s/run':>6}  missed>=10 sigma")
    for r in rows:
        fx = r["false"] / pfa if np.isfinite(r["false"]) else np.nan
        print(f"{r['network']:<7} {r['rate']:>4.0%} {r['method']:<8} {r['n_obs']:>5} {r['blunders']:>4} "
              f"{r['det']:>6.3f} {r['det10']:>7.3f} {r['det5_10']:>7.3f} {r['false']:>7.4f} {fx:>5.1f} "
              f"{r['own']:>4} {r['shift_max']:>9.2f} {r['shift_med']:>6.2f} {r['ideal_max']:>15.2f} {r['t']:>6.2f}  "
              f"{r['missed10'] or ''}")
    kv = []
    for net in dict.fromkeys(r["network"] for r in rows):
        for m in ("snooping", "robust"):
            sel = [r for r in rows if r["network"] == net and r["method"] == m]
            kv.append(f"{net}_{m}_det10_min={min(r['det10'] for r in sel):.3f}")
            kv.append(f"{net}_{m}_det_min={min(r['det'] for r in sel):.3f}")
            kv.append(f"{net}_{m}_false_max={max(r['false'] for r in sel):.4f}")
            kv.append(f"{net}_{m}_shift_max={max(r['shift_max'] for r in sel):.2f}")
            kv.append(f"{net}_{m}_shift_vs_same_removed_max={max(r['ideal_max'] for r in sel):.2f}")
        ls = [r for r in rows if r["network"] == net and r["method"] == "ls"]
        kv.append(f"{net}_ls_shift_max={max(r['shift_max'] for r in ls):.1f}")
    kv.append(f"expected_false={pfa:.4f}")
    kv.append(f"seconds={time.perf_counter() - t0:.0f}")
    print("RESULT " + " ".join(kv))


if __name__ == "__main__":
    main()
