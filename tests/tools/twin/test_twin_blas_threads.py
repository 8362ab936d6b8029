"""The twin's fit runs on one BLAS thread and gives the caller's setting back."""

from __future__ import annotations

from threadpoolctl import threadpool_info, threadpool_limits

from forcelearn.tools.twin.fit import fit_twin, one_blas_thread


def _blas_threads() -> list[int]:
    return [int(pool["num_threads"]) for pool in threadpool_info()
            if pool["user_api"] == "blas"]


def test_a_wrapped_call_sees_one_blas_thread_and_restores_the_callers() -> None:
    """Inside: 1 thread per BLAS library; after: what the caller had set (2 here)."""
    seen = one_blas_thread(_blas_threads)
    with threadpool_limits(limits=2, user_api="blas"):
        before = _blas_threads()
        assert seen() == [1] * len(before)
        assert _blas_threads() == before


def test_the_fit_is_wrapped() -> None:
    """fit_twin is the limited wrapper of the fit (functools.wraps keeps the original)."""
    assert fit_twin.__wrapped__.__name__ == "fit_twin"  # type: ignore[attr-defined]
