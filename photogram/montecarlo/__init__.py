"""Monte-Carlo accuracy of a photogrammetric chain (``photogram montecarlo``).

A ``[montecarlo]`` section names the chain (an ``orient`` or ``calibrate``
project, optionally an ``intersect`` project), what to perturb and how many
runs; :func:`run_montecarlo` builds the chain once (:class:`Chain`: truth
world, the engine's adjustment and intersect problems), propagates its covariance to
first order, runs the trials in chunks (this process, local processes or a
Dask cluster, resumable) and writes the comparison of empirical and
propagated sigmas. See docs/montecarlo.md.
"""

from __future__ import annotations

import dataclasses
import logging
import time
from pathlib import Path

from photogram.errors import InputError
from photogram.project.reader import MAX_RUNS, MAX_WORKERS

__all__ = ["run_montecarlo", "Chain", "Runner"]

log = logging.getLogger("photogram")


def __getattr__(name):          # lazy: the kernels import scipy and pandas
    if name == "Chain":
        from photogram.montecarlo.chain import Chain
        return Chain
    if name == "Runner":
        from photogram.montecarlo.execute import Runner
        return Runner
    raise AttributeError(name)


def settings_of(project, *, runs=None, seed=None, workers=None, scheduler=None, chunk=None):
    """The project's ``[montecarlo]`` settings with command-line overrides."""
    s = project.montecarlo
    if s is None:
        raise InputError("the project has no [montecarlo] section", file=project.path,
                         hint='add [montecarlo] with orient = "..." (see docs/montecarlo.md)')
    changes = {}
    for key, value in (("runs", runs), ("seed", seed), ("workers", workers),
                       ("scheduler", scheduler), ("chunk", chunk)):
        if value is not None:
            changes[key] = value
    for key in ("runs", "workers", "chunk"):
        if key in changes and int(changes[key]) < 1:
            raise InputError(f"--{key} must be at least 1, not {changes[key]}",
                             hint=f"e.g. --{key} 1000" if key == "runs" else None)
    for key, top in (("runs", MAX_RUNS), ("workers", MAX_WORKERS)):
        if key in changes and int(changes[key]) > top:
            raise InputError(f"--{key} must be at most {top}, not {changes[key]}",
                             hint="1000 runs give sigmas to 2 %" if key == "runs"
                             else "one worker per CPU core")
    if "seed" in changes and int(changes["seed"]) < 0:
        raise InputError(f"--seed must be >= 0, not {changes['seed']}")
    if changes.get("scheduler") is not None and \
            not str(changes["scheduler"]).startswith(("tcp://", "tls://", "inproc://")):
        raise InputError(f"--scheduler must be an address like tcp://HOST:PORT, "
                         f"not '{changes['scheduler']}'")
    return dataclasses.replace(s, **changes)


#: largest number of sample values (runs x output quantities) kept in memory
MAX_SAMPLE_VALUES = 200_000_000          # 1.6 GB of float64


def run_montecarlo(project, *, runs=None, seed=None, workers=None, scheduler=None,
                   chunk=None, output=None, progress=True, on_chunk=None, force=False):
    """Run (or resume) the Monte-Carlo simulation of a chain project.

    Finished runs in the output folder's ``samples/`` are reused only if
    they were computed from the same input files (by content), settings
    and program (:mod:`photogram.montecarlo.manifest`); ``force`` computes
    every run again. The cluster address ``scheduler`` comes only from the
    caller (``--scheduler``), never from the project file.

    Returns ``(folder, summary)``; the files are described in
    :mod:`photogram.montecarlo.report`. The library computes and writes the
    results files; ``report.pdf`` is the command's
    (:func:`photogram.commands.montecarlo.montecarlo`).
    """
    from photogram.montecarlo.chain import Chain
    from photogram.montecarlo.execute import Runner
    from photogram.montecarlo.report import write_report
    from photogram.project.atomic import atomic_write_text
    s = settings_of(project, runs=runs, seed=seed, workers=workers, scheduler=scheduler,
                    chunk=chunk)
    folder = Path(output) if output else project.output_folder()
    folder.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    chain = Chain(s)
    n_out = len(chain.outputs.names)
    if s.runs * n_out > MAX_SAMPLE_VALUES:
        raise InputError(f"{s.runs} runs of {n_out} quantities are {s.runs * n_out:.3g} values, "
                         f"more than {MAX_SAMPLE_VALUES:.3g} (1.6 GB) in memory",
                         file=project.path, hint=f"at most {MAX_SAMPLE_VALUES // n_out} runs "
                                                 f"for this chain")
    sigma_prop, sigma_cmd = chain.propagate()
    t_setup = time.perf_counter() - t0
    runner = Runner(chain, folder, runs=s.runs, seed=s.seed, chunk=s.chunk, workers=s.workers,
                    scheduler=s.scheduler, progress=progress, on_chunk=on_chunk,
                    force=force)
    samples, failed, info = runner.run()
    info.update({"seed": s.seed, "setup_seconds": t_setup})
    summary = write_report(folder, chain, samples, failed, sigma_prop, sigma_cmd, info,
                           project=project)
    lines = [f"photogram montecarlo {project.path}",
             f"runs: {summary['runs']} ({summary['failed']} failed), seed {s.seed}, "
             f"perturb {', '.join(s.perturb)}, truth {s.truth}",
             f"engine: {info['engine']}, workers {s.workers}, chunk {s.chunk}; "
             f"{info['runs_computed']} computed, {info['runs_resumed']} resumed, "
             f"{info['seconds']:.2f} s"]
    for g, h in summary["headline"].items():
        r = h["ratio"]
        lines.append(f"{g}: sigma_mc / sigma_prop median {r['median']:.3f} "
                     f"({r['min']:.3f} .. {r['max']:.3f})")
    atomic_write_text(folder / "log.txt", "\n".join(lines) + "\n")
    return folder, summary
