"""`photogram montecarlo PROJECT`: Monte-Carlo accuracy of a chain
(orient or calibrate, then optionally intersect); see docs/montecarlo.md."""

from __future__ import annotations

from photogram.montecarlo import run_montecarlo


def run(project, args=None):
    folder, summary = run_montecarlo(
        project, runs=getattr(args, "runs", None), seed=getattr(args, "seed", None),
        workers=getattr(args, "workers", None), scheduler=getattr(args, "scheduler", None),
        force=bool(getattr(args, "force", False)))
    if not getattr(args, "quiet", False):
        parts = [f"{g} {h['ratio']['median']:.2f}" for g, h in summary["headline"].items()]
        ex = summary["execution"]
        print(f"montecarlo: {summary['runs']} runs ({summary['failed']} failed) in "
              f"{ex['seconds']:.1f} s; sigma_mc/sigma_prop median: {', '.join(parts)}; "
              f"results in {folder}")
    return 0
