"""A diagnosis's answer must not depend on the machine's BLAS thread count: both diagnoses
run on one thread (calibration/diagnosis/threads.py says what two threads changed)."""
import numpy as np
from threadpoolctl import threadpool_info, threadpool_limits

from calibration.diagnosis.diagnose import diagnose
from calibration.diagnosis.stationary import diagnose_stationary
from calibration.diagnosis.threads import one_blas_thread


def _blas_threads():
    return [i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"]


def test_a_function_pinned_to_one_blas_thread_runs_on_one_and_leaves_the_setting_as_it_was():
    @one_blas_thread
    def inside():
        np.linalg.eigh(np.eye(64))  # some BLAS work
        return _blas_threads()

    with threadpool_limits(limits=2, user_api="blas"):
        before = _blas_threads()
        assert before and all(n == 2 for n in before)
        assert inside() == [1] * len(before)
        assert _blas_threads() == before


def test_both_diagnoses_are_pinned_to_one_blas_thread():
    for entry in (diagnose, diagnose_stationary):
        assert entry.__wrapped__.__name__ == entry.__name__  # the one_blas_thread wrapper
        assert entry.__code__ is one_blas_thread(lambda: None).__code__
