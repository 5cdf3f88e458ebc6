"""The mocap solvers run with one BLAS thread (photogram.mocap.reconstruction.blas):
the policy of photogram/__init__.py, applied at run time because numpy may
have been imported first (as here, under pytest)."""

import numpy as np
from threadpoolctl import threadpool_info

from photogram.mocap.reconstruction.blas import one_blas_thread
from photogram.mocap.reconstruction.joint_solver import solve_joint


def _blas_threads():
    return sorted({i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"})


def test_decorated_functions_run_with_one_blas_thread_and_restore_the_count(monkeypatch):
    from threadpoolctl import threadpool_limits
    monkeypatch.delenv("OPENBLAS_NUM_THREADS", raising=False)
    with threadpool_limits(limits=2, user_api="blas"):         # as without the policy
        before = _blas_threads()
        assert before == [2], before
        inside = one_blas_thread(_blas_threads)()
        assert inside == [1]
        assert _blas_threads() == before
    assert getattr(solve_joint, "__wrapped__", None) is not None       # the solver is wrapped
    # a decorated function still returns what it computes
    A = np.array([[4.0, 1.0], [1.0, 3.0]])
    assert np.allclose(one_blas_thread(np.linalg.solve)(A, [1.0, 2.0]),
                       np.linalg.solve(A, [1.0, 2.0]))


def test_a_thread_count_the_user_set_is_respected(monkeypatch):
    from threadpoolctl import threadpool_limits
    monkeypatch.setenv("OPENBLAS_NUM_THREADS", "2")
    with threadpool_limits(limits=2, user_api="blas"):
        assert one_blas_thread(_blas_threads)() == [2]


def test_nested_calls_keep_one_thread_and_the_outer_call_restores_the_count(monkeypatch):
    from threadpoolctl import threadpool_limits
    monkeypatch.delenv("OPENBLAS_NUM_THREADS", raising=False)

    @one_blas_thread
    def outer():
        return _blas_threads(), one_blas_thread(_blas_threads)(), _blas_threads()

    with threadpool_limits(limits=2, user_api="blas"):
        assert outer() == ([1], [1], [1])
        assert _blas_threads() == [2]
        assert one_blas_thread(_blas_threads)() == [1]     # a later call limits again
