"""A diagnosis runs its linear algebra on one BLAS thread, whatever the machine's setting:
a speed choice. Its matrices have a few hundred rows, where a second thread costs more
than it gives (one stationary diagnosis: 100 s on one thread, 136 s on two).

It used to be a guard as well: the same campaign (stationary seed 4535, a bracketed
sensor) was diagnosed with an equipment gain of 28.4 % on one thread and -234 % on two.
The amplifier was the box model's reduced bases. The two bogies give exactly equal pairs
of eigenvalues, whose shapes an eigen-solver returns in whatever rotation round-off picks
(on two threads turned by up to 80 degrees), and a parameter derivative that is zero but
for round-off was normalised into a unit vector of noise: a basis built on two threads gave
frequencies 3 % from its centre that differed from one thread's by 8e-6, and every swarm
and refinement on it went its own way from there. Equal pairs now get canonical shapes and
round-off-only directions are left out (:func:`calibration.models.box.reduced.canonical_vectors`,
``NEGLIGIBLE``): the two bases agree to 2e-11 (tests/test_diagnosis_threads.py).
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
