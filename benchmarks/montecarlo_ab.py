"""CPU time of one Monte-Carlo run, this checkout against another, side by
side: two worker processes (one per checkout, single-threaded BLAS) run
rounds of ``--trials`` runs of ``Chain.trial`` (projects/jumps/montecarlo.prj)
in alternation; the best round and the median of the per-round ratios are
robust to a shared machine whose speed drifts between minutes.

The other checkout needs the same lab and field results (copy
projects/lab/results* and projects/field/results there, or run make demo in
it). Issue 17 compared against def3da7 (the lean Monte-Carlo kernels):

    git worktree add /tmp/mc-old def3da7
    cp -r projects/lab/results projects/field/results ... /tmp/mc-old/projects/...
    .venv/bin/python benchmarks/montecarlo_ab.py /tmp/mc-old --rounds 30 --trials 50

Prints one line per checkout and ends with a RESULT line (ratio < 1: this
checkout is faster).
"""

import argparse
import os
import statistics
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

WORKER = r"""
import os, sys, time
import numpy as np
from photogram.project import read_project
from photogram.montecarlo import settings_of
from photogram.montecarlo.chain import Chain
os.chdir(sys.argv[1])
chain = Chain(settings_of(read_project("projects/jumps/montecarlo.prj")))
seeds = np.random.SeedSequence(1).spawn(int(sys.argv[2]))
for s in seeds[:5]:
    chain.trial(s)
print("ready", flush=True)
for line in sys.stdin:
    t = time.process_time()
    for s in seeds:
        chain.trial(s)
    print((time.process_time() - t) / len(seeds) * 1e3, flush=True)
"""


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("other", help="the other checkout (its photogram is imported from there)")
    ap.add_argument("--rounds", type=int, default=30)
    ap.add_argument("--trials", type=int, default=50)
    a = ap.parse_args(argv)
    env = dict(os.environ, OMP_NUM_THREADS="1", OPENBLAS_NUM_THREADS="1", MKL_NUM_THREADS="1")
    procs = {}
    for name, path in (("this", ROOT), ("other", Path(a.other).resolve())):
        procs[name] = subprocess.Popen(
            [sys.executable, "-c", WORKER, str(path), str(a.trials)], stdin=subprocess.PIPE,
            stdout=subprocess.PIPE, text=True, env=dict(env, PYTHONPATH=str(path)))
    for p in procs.values():
        if p.stdout.readline().strip() != "ready":
            sys.exit("a worker did not start (see its error above)")
    ms = {"this": [], "other": []}
    for i in range(a.rounds):
        order = ("this", "other") if i % 2 == 0 else ("other", "this")
        for name in order:
            procs[name].stdin.write("go\n")
            procs[name].stdin.flush()
            ms[name].append(float(procs[name].stdout.readline()))
    for p in procs.values():
        p.stdin.close()
        p.wait()
    for name, v in ms.items():
        print(f"{name}: best {min(v):.3f} median {statistics.median(v):.3f} ms per run")
    ratios = [t / o for t, o in zip(ms["this"], ms["other"])]
    print(f"RESULT rounds={a.rounds} trials={a.trials} this_best_ms={min(ms['this']):.3f} "
          f"other_best_ms={min(ms['other']):.3f} "
          f"best_ratio={min(ms['this']) / min(ms['other']):.3f} "
          f"median_round_ratio={statistics.median(ratios):.3f}")


if __name__ == "__main__":
    main()
