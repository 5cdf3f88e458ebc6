"""Fuzzing figures (docs/reliability.md, section 1): the malformed-input
corpus of tests/fuzz/corpus.py and the hypothesis properties of
tests/test_fuzz_hypothesis.py, with their fixed example counts
(derandomized: the same cases every run).

Every case must end with exit code 0 or 2 (on 2: one line on stderr naming
the input file, and its line where the input is line-based) and never
with a traceback. Prints the failing cases, then

    RESULT cases=... corpus=... hypothesis=... tracebacks=... exit2=... ok=... failed=... seconds=...

Run: .venv/bin/python benchmarks/fuzz.py [--only PREFIX] [--no-hypothesis]
"""

import os

os.environ.setdefault("PHOTOGRAM_FUZZ_FULL", "1")     # every case and example

import argparse  # noqa: E402
import logging
import sys
import tempfile
import time
import warnings
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

import photogram  # noqa: E402,F401  (single-threaded BLAS before numpy)

from fuzz.corpus import build_cases, run_case, stage  # noqa: E402


def corpus(only: str | None, verbose: bool = False) -> Counter:
    tally = Counter()
    with tempfile.TemporaryDirectory(prefix="fuzz-") as tmp:
        base = stage(Path(tmp) / "base")
        cases = [c for c in build_cases(base) if only is None or c.id.startswith(only)]
        times = Counter()
        for k, case in enumerate(cases):
            t = time.perf_counter()
            with tempfile.TemporaryDirectory(dir=tmp) as work:
                res, bad = run_case(case, base, Path(work))
            times[case.id] = time.perf_counter() - t
            times["group " + case.id.split(":")[0]] += times[case.id]
            tally["cases"] += 1
            tally[f"exit{res.rc}"] += 1
            tally["tracebacks"] += "Traceback" in res.out + res.err
            if res.rc == 2 and not res.err.rstrip().endswith(")"):
                tally["no_hint"] += 1         # messages end with "(hint)"
                if verbose:
                    print(f"no hint: {case.id}: {res.err.strip()[-160:]}")
            if bad:
                tally["failed"] += 1
                print(f"FAIL {case.id}: {bad}", flush=True)
        if verbose:
            for key, t in times.most_common(25):
                print(f"  {t:6.2f} s  {key}")
    return tally


def hypothesis() -> Counter:
    import test_fuzz_hypothesis as th
    failed = 0
    for name in sorted(n for n in dir(th) if n.startswith("test_")):
        try:
            getattr(th, name)()
        except Exception as exc:  # noqa: BLE001  (a falsified property)
            failed += 1
            print(f"FAIL {name}: {str(exc).splitlines()[0][:300]}", flush=True)
    s = th.STATS
    return Counter(cases=s["examples"], exit0=s["exit0"], exit2=s["exit2"],
                   tracebacks=s["tracebacks"], failed=failed,
                   exit_other=s["examples"] - s["exit0"] - s["exit2"])


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", help="corpus cases whose id starts with this")
    parser.add_argument("--no-hypothesis", action="store_true")
    parser.add_argument("--times", action="store_true", help="print the slowest cases")
    args = parser.parse_args(argv)
    logging.disable(logging.WARNING)
    warnings.simplefilter("ignore")
    t0 = time.perf_counter()
    c = corpus(args.only, args.times)
    h = Counter() if args.no_hypothesis else hypothesis()
    total = c + h
    print(f"corpus: {c['cases']} cases, exit 0: {c['exit0']}, exit 2: {c['exit2']} "
          f"({c['no_hint']} without a hint), failed: {c['failed']}")
    print(f"hypothesis: {h['cases']} examples, exit 0: {h['exit0']}, exit 2: {h['exit2']}, "
          f"failed properties: {h['failed']}")
    print(f"RESULT cases={total['cases']} corpus={c['cases']} hypothesis={h['cases']} "
          f"tracebacks={total['tracebacks']} exit2={total['exit2']} ok={total['exit0']} "
          f"failed={total['failed']} seconds={time.perf_counter() - t0:.0f}")
    return 1 if total["failed"] or total["tracebacks"] else 0


if __name__ == "__main__":
    sys.exit(main())
