"""A pytest plugin that records the CPU time of every test (benchmarks only).

Use: ``python -m pytest -p pytest_cpu ...`` with ``benchmarks/`` on
PYTHONPATH. Every test's setup + call + teardown is charged with the CPU
seconds of the pytest process (``time.process_time``) plus those of the
child processes that ended meanwhile (``resource.getrusage(RUSAGE_CHILDREN)``,
user + system). The peak resident memory of the pytest process and of its
largest child so far is written too. The table goes to the file named by the
environment variable ``PYTEST_CPU_LOG`` (default ``pytest_cpu.tsv``):
one line per test, ``nodeid  cpu_s  child_cpu_s  self_maxrss_mb
child_maxrss_mb``; the summary per file is printed at the end.
"""

from __future__ import annotations

import os
import resource
import time
from collections import defaultdict

import pytest

_ROWS: list[tuple[str, float, float, float, float]] = []


def _children() -> tuple[float, float]:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime, ru.ru_maxrss / 1024.0


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item, nextitem):
    """Charge the test's whole protocol (setup, call, teardown)."""
    cpu0 = time.process_time()
    child0, _ = _children()
    yield
    cpu = time.process_time() - cpu0
    child, child_rss = _children()
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    _ROWS.append((item.nodeid, cpu, child - child0, rss, child_rss))


def pytest_sessionfinish(session, exitstatus):
    """Write the table and print the per-file sums."""
    path = os.environ.get("PYTEST_CPU_LOG", "pytest_cpu.tsv")
    with open(path, "w", encoding="utf-8") as out:
        for row in _ROWS:
            out.write("%s\t%.2f\t%.2f\t%.0f\t%.0f\n" % row)
    files: dict[str, list[float]] = defaultdict(lambda: [0.0, 0.0, 0])
    for nodeid, cpu, child, _, _ in _ROWS:
        acc = files[nodeid.split("::")[0]]
        acc[0] += cpu
        acc[1] += child
        acc[2] += 1
    rep = session.config.pluginmanager.get_plugin("terminalreporter")
    if rep is None:
        return
    rep.write_line("CPU per file (self + children, s):")
    for name, (cpu, child, n) in sorted(files.items(), key=lambda kv: -(kv[1][0] + kv[1][1])):
        rep.write_line("%8.1f %8.1f %4d  %s" % (cpu + child, child, n, name))
    total = sum(c + k for c, k, _ in files.values())
    rep.write_line("%8.1f total; peak RSS self %.0f MB, largest child %.0f MB" % (
        total, max((r[3] for r in _ROWS), default=0), max((r[4] for r in _ROWS), default=0)))
