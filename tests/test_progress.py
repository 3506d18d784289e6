"""Progress on stderr (calibration/progress.py): counted bars with a time estimate through
tqdm for the command line, plain messages for a plain callable, nothing with --quiet."""
import io

import numpy as np

from railcal.common import progress_for
from calibration.optimisers.base import SearchParameter
from calibration.optimisers.pso import PSOSettings, particle_swarm
from calibration.progress import Progress, counter


def test_a_bar_counts_to_its_total_with_rate_and_estimate_on_the_stream():
    stream = io.StringIO()
    with counter(Progress(stream), 5, "swarm 1 of 2", unit="it") as bar:
        for _ in range(5):
            bar.update()
    text = stream.getvalue()
    assert "swarm 1 of 2" in text and "5/5" in text and "it/s" in text


def test_a_plain_callable_gets_the_description_once_and_a_silent_bar():
    got = []
    with counter(got.append, 3, "refining") as bar:
        bar.update(3)
        bar.set_postfix_str("done")
    assert got == ["refining"]


def test_messages_go_above_the_bar_and_quiet_turns_everything_off():
    stream = io.StringIO()
    Progress(stream)("1/11 synthesising")
    assert stream.getvalue() == "1/11 synthesising\n"

    class Args:
        quiet = True

    assert progress_for(Args()) is None
    Args.quiet = False
    assert isinstance(progress_for(Args()), Progress)


def test_the_swarm_reports_every_iteration_and_its_path_does_not_depend_on_being_watched():
    """The iteration hook only observes: the same seed gives the same best with and without it."""
    space = (SearchParameter("a", 0.0, 1.0, -2.0, 2.0, 0.01), SearchParameter("b", 0.0, 1.0, -2.0, 2.0, 0.01))

    def sphere(X):
        return np.sum((np.atleast_2d(X) - 0.5) ** 2, axis=1)

    seen = []
    settings = PSOSettings(particles=20, iterations=15)
    watched = particle_swarm(sphere, space, np.random.default_rng(3), settings=settings,
                             on_iteration=lambda it, best: seen.append((it, best)))
    plain = particle_swarm(sphere, space, np.random.default_rng(3), settings=settings)
    assert [it for it, _ in seen] == list(range(1, 16))
    assert all(b1 >= b2 for (_, b1), (_, b2) in zip(seen, seen[1:]))  # the best never gets worse
    assert np.array_equal(watched.best, plain.best)
