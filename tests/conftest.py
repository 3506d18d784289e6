"""Shared fixtures: small campaigns written by the project's own writer; the BLAS thread
cap of ``make test``'s workers; the ``slow`` tier; every figure saved with units on its axes."""
from __future__ import annotations

import os
import re

import numpy as np
import pytest

from calibration.data.campaign import CampaignMeta, Prior, Sensor
from calibration.data.outputs import CampaignWriter
from calibration.truth.in_service import InServiceSettings, synth_in_service
from calibration.truth.track import LineSpec

TINY_SENSORS = (
    Sensor("bogie1_acc_z", "acceleration", "g", "bogie1", "z", (8.5, 0.6, 0.7)),
    Sensor("bogie1_gyro_pitch", "angular_velocity", "deg/s", "bogie1", "pitch", (8.5, 0.6, 0.7), 2.0),
)


def tiny_meta(**changes) -> CampaignMeta:
    base = dict(kind="in_service", name="tiny", vehicle="test car", sensors=TINY_SENSORS, sampling_rate=100.0,
                geometry={"bogie_semi_spacing": 8.0, "semi_wheelbase": 1.25},
                priors={"m_v": Prior(38747.0, 36850.0, 40644.0)})
    base.update(changes)
    return CampaignMeta(**base)


def tiny_columns(n: int = 400) -> dict[str, np.ndarray]:
    t = np.arange(n) / 100.0
    return {"time": t, "distance": 30.0 * t, "speed": np.full(n, 30.0),
            "bogie1_acc_z": 1.0 + 0.01 * np.sin(2 * np.pi * 5 * t),
            "bogie1_gyro_pitch": 0.5 * np.sin(2 * np.pi * 7 * t)}


def _cap_blas_threads_per_worker():
    """For speed only, never for results: under pytest-xdist each worker gets at most
    cores / workers BLAS threads, so that ``make test``'s workers do not oversubscribe the
    cores (two workers with two OpenBLAS threads each on two cores ran test_ema.py at
    52 s instead of 22 s). Results do not depend on it (tests/test_ema.py and
    test_box_calibration.py compare one and two threads); ``RAILCAL_TEST_BLAS_CAP=off``
    runs without it, and a run without xdist (``-n 0``) never has it. The processes a
    worker starts inherit it through the BLAS libraries' environment variables."""
    workers = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT", "1"))
    if workers <= 1 or os.environ.get("RAILCAL_TEST_BLAS_CAP", "on") == "off":
        return None
    import scipy.linalg  # noqa: F401  (scipy's own OpenBLAS must be loaded for the cap to reach it)
    from threadpoolctl import threadpool_limits

    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count() or 1
    cap = max(1, cores // workers)
    # the same cap for the processes a test starts (the README tour's railcal commands, an
    # import check): threadpoolctl reaches this process only, and a child's OpenBLAS took
    # every core beside the other worker (the shaker tour: 505 s of wall time for 305 s of
    # CPU time in a suite run)
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[var] = str(cap)
    return threadpool_limits(cap, user_api="blas")


_BLAS_CAP = _cap_blas_threads_per_worker()


#: fixtures that synthesise a campaign, build FMUs or diagnose one (seconds on one core of
#: the 2-core development machine): a test using one is in the ``slow`` tier, which
#: ``make check`` leaves out and ``make test`` runs. A test that synthesises or diagnoses a
#: campaign itself is marked ``slow`` where it is defined.
SLOW_FIXTURES = {
    "synthetic_campaign": 32,  # a six-journey in-service campaign
    "car_fmus": 36,  # the car FMU compiled for FMI 2 and 3
    "shaker": 26,  # test_box_calibration.py: a 240 s shaker test, synthesised and identified
    "diagnosed": 125,  # test_diagnosis_excitation.py: a shaker campaign (bracketed sensor), diagnosed
    "box_fmus": 6,  # test_fmu_box.py: the box FMU for FMI 2 and 3
    "over_the_track": 6,  # test_reference_box.py: exudyn, railcal and the FMU over a track
    "equipment_campaign": 6,  # test_truth_excitation_effects.py: synthesised shaker campaigns
    "softening_campaign": 4,
    "example_fmus": 40,  # test_fmu_fuzz.py: every registry model's FMU (the box's reduction included), fuzzed
    "cli_fmus": 24,  # test_fmu_models.py: every registry model's FMU built through export-fmu, FMI 2 and 3
}


def _cost(item) -> float:
    """A rough cost of a test [s], for the order of the work: a ``slow(seconds=...)`` mark,
    else the dearest :data:`SLOW_FIXTURES` fixture it uses, else 20 s for a test marked
    ``slow`` and 0.2 s for the rest."""
    mark = item.get_closest_marker("slow")
    if mark is not None and "seconds" in mark.kwargs:
        return float(mark.kwargs["seconds"])
    fixtures = SLOW_FIXTURES.keys() & set(getattr(item, "fixturenames", ()))
    if fixtures:
        return float(max(SLOW_FIXTURES[f] for f in fixtures))
    return 20.0 if mark is not None else 0.2


#: the session fixtures of :data:`SLOW_FIXTURES`: the files using one are one group, so that
#: one worker builds it once (each xdist worker has its own session)
SESSION_SLOW_FIXTURES = ("synthetic_campaign", "synthetic_identification", "car_fmus")


def _files_sharing_session_fixtures(items) -> dict[str, str]:
    """file -> the group of the files that use the same :data:`SESSION_SLOW_FIXTURES`
    fixture, named by its first file (files joined transitively)."""
    users: dict[str, set[str]] = {}
    for item in items:
        for name in SESSION_SLOW_FIXTURES:
            if name in getattr(item, "fixturenames", ()):
                users.setdefault(name, set()).add(item.nodeid.split("::")[0])
    group: dict[str, str] = {}
    for files in users.values():
        joined = set(files) | {f2 for f in files if f in group for f2, g in group.items() if g == group[f]}
        name = min(joined)
        group.update({f: name for f in joined})
    return group


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    """Groups for pytest-xdist's ``--dist loadgroup`` (``make test``): every test file runs on
    one worker, so its module and session fixtures are built once, except tests marked
    ``spread`` (a diagnosed campaign of a minute or two each), which are a group each so
    that the workers share them. Tests using a :data:`SLOW_FIXTURES` fixture are marked
    ``slow``. The groups are ordered dearest first (``make test`` keeps this order with
    ``--no-loadscope-reorder``): the workers hand out groups in order, and a two-minute test
    left to the end ran alone while the other worker idled.

    ``tryfirst``: an xdist worker reads the ``xdist_group`` marks in its own
    ``pytest_collection_modifyitems``, registered after this conftest and so called before
    it: without ``tryfirst`` it saw no marks (see :class:`_GroupInNodeId` for the rest)."""
    group_of, cost = {}, {}
    file_group = _files_sharing_session_fixtures(items)
    for item in items:
        if SLOW_FIXTURES.keys() & set(getattr(item, "fixturenames", ())):
            item.add_marker(pytest.mark.slow)
        path = item.nodeid.split("::")[0]
        group = item.nodeid if item.get_closest_marker("spread") else file_group.get(path, path)
        item.add_marker(pytest.mark.xdist_group(group))
        group_of[item.nodeid] = group
        cost[group] = cost.get(group, 0.0) + _cost(item)
    order = {item.nodeid: k for k, item in enumerate(items)}
    items.sort(key=lambda item: (-cost[group_of[item.nodeid]], order[item.nodeid]))


class _GroupInNodeId:
    """pytest-xdist 3.8 sends a test's group to the scheduler as an ``@group`` suffix of its
    node id, written to ``item._nodeid``; pytest 9.2 builds node ids from the structured
    ``item._id`` and ignores it (pytest-dev/pytest-xdist#1386, open). The groups were then
    lost without a word: every test was a group of its own, the files' tests were dealt to
    both workers, and each worker built the session and module fixtures again (the synthetic
    campaign, the shaker test, the FMUs). This writes the suffix where pytest reads it, after
    xdist's own hook, unless the id already carries it (an xdist that does it itself)."""

    @pytest.hookimpl(trylast=True)
    def pytest_collection_modifyitems(self, config, items):
        if not config.getvalue("loadgroup"):
            return
        from _pytest.nodeid import NodeId

        for item in items:
            groups = sorted({str(m.args[0] if m.args else m.kwargs.get("name", "default"))
                             for m in item.iter_markers("xdist_group")})
            suffix = "@" + "_".join(groups)
            if groups and not item.nodeid.endswith(suffix) and hasattr(item, "_id"):
                item._id = NodeId.parse(item.nodeid + suffix)


def pytest_configure(config):
    if hasattr(config, "workerinput"):  # an xdist worker
        config.pluginmanager.register(_GroupInNodeId(), "railcal-xdist-group-in-node-id")


# ------------------------------------------------------------------ figures
#: a unit on an axis label: "[m/s^2]", "[-]", "[(m/s^2)^2/Hz]"
_UNIT = re.compile(r"\[[^\]]+\]")
_UNLABELLED: list[str] = []


def axes_without_units(fig) -> list[str]:
    """'<axes title>: x' for each axis of ``fig`` that shows data and ticks but whose label
    (or, on shared axes, a sibling's: subplots label the outer row or column) has no unit.
    An axis of names (its ticks labelled with words, as a MAC matrix's modes) has no unit,
    but needs a label saying what the names are."""
    missing = []
    for ax in fig.axes:
        if not ax.axison or not (ax.lines or ax.images or ax.collections or ax.patches):
            continue
        for which in ("x", "y"):
            axis = ax.xaxis if which == "x" else ax.yaxis
            if not axis.get_visible() or len(axis.get_majorticklocs()) == 0:
                continue  # a colorbar's short side
            siblings = (ax.get_shared_x_axes() if which == "x" else ax.get_shared_y_axes()).get_siblings(ax)
            labels = [o.get_xlabel() if which == "x" else o.get_ylabel() for o in siblings]
            ticks = axis.get_major_formatter().format_ticks(axis.get_majorticklocs())
            named = any(any(c.isalpha() for c in t) and not t.startswith("$") for t in ticks)  # $: a number's mathtext
            if not any(label.strip() if named else _UNIT.search(label) for label in labels):
                title = ax.get_title() or (fig._suptitle.get_text() if fig._suptitle else "untitled")
                missing.append(f"{title!r}: {which} ({(ax.get_xlabel() if which == 'x' else ax.get_ylabel())!r})")
    return missing


@pytest.fixture(scope="session", autouse=True)
def _every_figure_is_checked_for_units():
    """Every figure any test makes, through any code path, is looked at as it is saved."""
    from matplotlib.figure import Figure

    save = Figure.savefig

    def checked(self, *args, **kwargs):
        _UNLABELLED.extend(axes_without_units(self))
        return save(self, *args, **kwargs)

    Figure.savefig = checked
    yield
    Figure.savefig = save


@pytest.fixture(autouse=True)
def _figures_have_units_on_both_axes():
    yield
    missing, _UNLABELLED[:] = list(_UNLABELLED), []
    assert not missing, f"figure axes without a unit in their label: {missing}"


@pytest.fixture
def tiny_campaign(tmp_path):
    """A valid two-sensor in-service campaign (CSV) with one run, 4 s at 100 Hz."""
    root = tmp_path / "tiny"
    with CampaignWriter(root, tiny_meta()) as w:
        w.write_run("run_a", tiny_columns())
        w.commit()
    return root


@pytest.fixture(scope="session")
def synthetic_campaign(tmp_path_factory):
    """A small synthetic in-service campaign from the truth simulator (Parquet), and its truth."""
    root = tmp_path_factory.mktemp("synth") / "campaign"
    truth = synth_in_service(root, seed=11, settings=InServiceSettings(journeys=6, line=LineSpec(length=24_000.0)),
                             fmt="parquet")
    return root, truth


@pytest.fixture(scope="session")
def synthetic_identification(synthetic_campaign, tmp_path_factory):
    """``railcal identify`` run once on the synthetic campaign: (its --out path, the
    one-line summary it printed, the identification it made: ``identify_in_service`` at its
    default settings, which test_identify.py examines, so that it is not made twice)."""
    import contextlib
    import io

    import calibration.identification.in_service as in_service
    from railcal.cli import main

    identify, made = in_service.identify_in_service, []

    def kept(*args, **kwargs):
        assert kwargs.get("settings", in_service.IdentifySettings()) == in_service.IdentifySettings()
        made.append(identify(*args, **kwargs))
        return made[-1]

    out = tmp_path_factory.mktemp("identified") / "new_folder" / "ident.json"  # a missing folder is created
    printed = io.StringIO()
    with pytest.MonkeyPatch.context() as patch, contextlib.redirect_stdout(printed):
        patch.setattr(in_service, "identify_in_service", kept)
        assert main(["identify", str(synthetic_campaign[0]), "--out", str(out), "--quiet"]) == 0
    (result,) = made
    return out, printed.getvalue(), result


COARSE_BOX_ORDERS = -4  # every panel order - 4: the shaker-test files stay fast, the physics is the same


@pytest.fixture(scope="session")
def coarse_box_model():
    """The Shinkansen-type box model at coarse panel orders, assembled once per session."""
    from calibration.models.box.shinkansen import shinkansen_model
    return shinkansen_model(COARSE_BOX_ORDERS)


@pytest.fixture(scope="session")
def model(coarse_box_model):
    """The box model of the excitation-test files (the coarse one)."""
    return coarse_box_model


# ------------------------------------------------------------------ FMUs
CAR_FMU_SPEED = 40.0  # [m/s]
CAR_FMU_START = 100.0  # [m] track distance of the carbody centre at t = 0


@pytest.fixture(scope="session")
def car_track(tmp_path_factory):
    """A synthetic track (900 m, 3-70 m wavelengths) as a track CSV and as the reference's
    spline (the FMU interpolates the file the same way)."""

    from fmu_src.reference import smooth_profile

    s, z, profile = smooth_profile(900.0, seed=3)
    path = tmp_path_factory.mktemp("track") / "track.csv"
    np.savetxt(path, np.column_stack([s, z]), delimiter=",", header="distance,level", comments="", fmt="%.17g")
    return path, profile


@pytest.fixture(scope="session")
def car_fmus(tmp_path_factory, car_track):
    """The car FMU (intercity trailer parameters, track in resources/) for FMI 2 and 3:
    (spec, {2: BuiltFMU, 3: BuiltFMU})."""
    from calibration.models.vehicles import INTERCITY_TRAILER
    from fmu_src.build import build_fmu
    from fmu_src.variables import car2d_spec

    out = tmp_path_factory.mktemp("fmus")
    spec = car2d_spec(INTERCITY_TRAILER.as_dict(), track=car_track[0])
    return spec, {v: build_fmu(spec, v, out / f"car{v}.fmu") for v in (2, 3)}


# ------------------------------------------------------------------ the model registry's FMUs
#: what makes a registry model's example calibration quick to build in tests: the box at
#: coarse panel orders (its full-order FMU takes long to build)
FAST_EXAMPLES = {"box": {"order_change": COARSE_BOX_ORDERS}}


@pytest.fixture(scope="session")
def example_calibration():
    """name -> a fresh copy of the example calibration of the registry's model ``name``
    (railcal.registry.MODELS), quick to build (:data:`FAST_EXAMPLES`)."""
    from railcal.registry import MODELS

    def make(name: str) -> dict:
        return {**MODELS[name].example_calibration(), **FAST_EXAMPLES.get(name, {})}

    return make
