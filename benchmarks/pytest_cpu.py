"""pytest plugin: CPU seconds and peak memory per test (docs/benchmarks.md,
the test suite).

For every test: CPU seconds of this process (``time.process_time``: user +
system) and of its finished child processes (``getrusage(RUSAGE_CHILDREN)``),
wall seconds, ``ru_maxrss`` of this process and of its largest child so
far, and the resident size after the test (what the session keeps); also
the CPU of collecting. Written as JSON to ``$PYTEST_CPU_OUT``
(default ``pytest_cpu.json``) at the end of the session::

    PYTHONPATH=$PWD:$PWD/benchmarks python -m pytest -q -p pytest_cpu tests/test_x.py
    python benchmarks/pytest_cpu.py pytest_cpu.json      # per file and slowest tests
"""

from __future__ import annotations

import collections
import json
import os
import resource
import sys
import time

import pytest

_ROWS: list = []
_SESSION: dict = {}


def _rss() -> int:
    """Resident set size of this process now (bytes; 0 where /proc is missing)."""
    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        return 0


def _now():
    s = resource.getrusage(resource.RUSAGE_SELF)
    c = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time(), c.ru_utime + c.ru_stime, s.ru_maxrss * 1024, c.ru_maxrss * 1024


def pytest_sessionstart(session):
    _SESSION["start"] = _now()


def pytest_collection_finish(session):
    _SESSION["collected"] = _now()


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    a, wall = _now(), time.perf_counter()
    yield
    b = _now()
    _ROWS.append({"id": item.nodeid, "cpu": b[0] - a[0], "children_cpu": b[1] - a[1],
                  "wall": time.perf_counter() - wall, "maxrss": b[2], "children_maxrss": b[3],
                  "rss": _rss()})


def pytest_sessionfinish(session):
    out = {"rows": _ROWS, "start": _SESSION.get("start"),
           "collected": _SESSION.get("collected"), "end": _now()}
    with open(os.environ.get("PYTEST_CPU_OUT", "pytest_cpu.json"), "w") as f:
        json.dump(out, f, indent=0)


def summary(path: str, n: int = 15) -> str:
    """Per file CPU seconds (children included) and the ``n`` costliest tests."""
    d = json.load(open(path))
    st, co, en = d["start"], d["collected"] or d["start"], d["end"]
    lines = [f"collecting: {co[0] - st[0]:.1f} s CPU; whole session {en[0] - st[0]:.1f} s "
             f"+ children {en[1] - st[1]:.1f} s; peak {en[2] / 1e9:.2f} GB, "
             f"largest child {en[3] / 1e9:.2f} GB"]
    files = collections.defaultdict(lambda: [0.0, 0])
    for r in d["rows"]:
        f = files[r["id"].split("::")[0]]
        f[0] += r["cpu"] + r["children_cpu"]
        f[1] += 1
    lines += [f"{v[0]:8.1f} s {v[1]:5d} tests  {k}"
              for k, v in sorted(files.items(), key=lambda kv: -kv[1][0])]
    lines += [f"{r['cpu'] + r['children_cpu']:8.1f} s  {r['maxrss'] / 1e9:.2f} GB  {r['id']}"
              for r in sorted(d["rows"], key=lambda r: -(r["cpu"] + r["children_cpu"]))[:n]]
    return "\n".join(lines)


if __name__ == "__main__":
    print(summary(sys.argv[1] if len(sys.argv) > 1 else "pytest_cpu.json"))
