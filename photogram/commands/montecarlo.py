"""`photogram montecarlo PROJECT`: Monte-Carlo accuracy of a chain
(orient or calibrate, then optionally intersect); see docs/montecarlo.md."""

from __future__ import annotations

from photogram.montecarlo import run_montecarlo


def montecarlo(project, report=True, **options):
    """Run (or resume) :func:`run_montecarlo` into the project's results
    folder through its staging folder, where the finished trials
    (``samples/``) of an interrupted run wait for the rerun
    (:mod:`photogram.project.results_folder`). Returns ``(folder, summary)``."""
    from photogram.project.output_policy import project_inputs
    from photogram.project.results_folder import staged_results
    with staged_results(project.output_folder(), command="montecarlo", resumable=True,
                        inputs=project_inputs(project)) as stage:
        _, summary = run_montecarlo(project, output=stage.path, **options)
        if report:
            write_pdf(stage.path)
    return stage.final, summary


def write_pdf(folder):
    """report.pdf of the results folder, as every command writes it (the
    library, photogram.montecarlo, computes; the command writes)."""
    import photogram.report
    photogram.report.write_report(folder)


def run(project, args=None):
    folder, summary = montecarlo(
        project, runs=getattr(args, "runs", None), seed=getattr(args, "seed", None),
        workers=getattr(args, "workers", None), scheduler=getattr(args, "scheduler", None),
        force=bool(getattr(args, "force", False)),
        report=not getattr(args, "no_report", False))
    if not getattr(args, "quiet", False):
        parts = [f"{g} {h['ratio']['median']:.2f}" for g, h in summary["headline"].items()]
        ex = summary["execution"]
        print(f"montecarlo: {summary['runs']} runs ({summary['failed']} failed) in "
              f"{ex['seconds']:.1f} s; sigma_mc/sigma_prop median: {', '.join(parts)}; "
              f"results in {folder}")
    return 0
