"""_threads.py: one BLAS thread inside the block, the previous limits and environment after it."""

import os

import numpy  # noqa: F401 — its OpenBLAS must be loaded for threadpoolctl to see it
from threadpoolctl import threadpool_info, threadpool_limits

from torsionfit._threads import single_blas_thread


def _blas_threads():
    return {i["filepath"]: i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"}


def test_single_blas_thread_limits_and_restores(monkeypatch):
    monkeypatch.delenv("OPENBLAS_NUM_THREADS", raising=False)
    with threadpool_limits(limits=2, user_api="blas"):
        before = _blas_threads()
        assert before and set(before.values()) == {2}
        with single_blas_thread():
            assert set(_blas_threads().values()) == {1}
            assert os.environ["OPENBLAS_NUM_THREADS"] == "1"  # for BLAS libraries loaded later
        assert _blas_threads() == before
        assert "OPENBLAS_NUM_THREADS" not in os.environ
