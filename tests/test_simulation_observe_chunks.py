"""photogram.simulation.network.observe projects the stations a few at a
time: the network must be the same, bit for bit, as projecting all at once."""

import numpy as np
import pytest

import photogram.simulation.network as network

# `make test-fast` leaves this module out (slow: docs/benchmarks.md, the test suite's slowest files).
pytestmark = pytest.mark.slow


def _same(a, b):
    for name in ("station", "point", "xy_true", "xy"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


def test_chunked_projection_equals_one_pass(monkeypatch):
    whole = network.wall_network(n_stations=12, n_points=300, rays=4, seed=5)
    for pairs in (1, 299, 301, 1000):          # one station per pass ... several
        monkeypatch.setattr(network, "_PAIRS", pairs)
        _same(network.wall_network(n_stations=12, n_points=300, rays=4, seed=5), whole)


def test_chunks_bound_the_memory_of_a_large_wall():
    import resource
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    net = network.wall_network(n_stations=150, n_points=8000, rays=4, seed=3)
    grown_mb = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before) / 1024
    assert len(net.station) > 30_000
    # all 1.2 million pairs at once took 1.5 GB, 200,000 pairs a pass 279 MB,
    # 50,000 (network._PAIRS) 76 MB
    assert grown_mb < 150, grown_mb
