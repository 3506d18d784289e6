"""A diagnosis runs its linear algebra on one BLAS thread, whatever the machine's setting:
a speed choice. Its matrices have a few hundred rows, where a second thread costs more
than it gives (one excitation-test diagnosis: 100 s on one thread, 136 s on two).

The answer does not depend on it: the reduced bases give the bogies' equal eigenvalue pairs
canonical shapes and leave round-off-only directions out
(:func:`calibration.models.box.parametric_basis.canonical_vectors`), so one and two threads agree to
2e-11 (tests/test_diagnosis_threads.py; docs/CHANGELOG.md tells how a campaign once split).
"""
from __future__ import annotations

import functools

from threadpoolctl import threadpool_limits


def one_blas_thread(func):
    """Run ``func`` with every loaded BLAS library limited to one thread."""
    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        with threadpool_limits(limits=1, user_api="blas"):
            return func(*args, **kwargs)
    return wrapper
