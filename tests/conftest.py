"""Before any test: the numba kernels compiled (or loaded from their cache) once, with no
time budget running. In a fresh clone compiling them takes about a minute, and a test's
first solve (or a CLI subprocess's) would otherwise spend its solver's time budget on it
on a slow machine; compiled here, they are cached next to the sources for every process
after."""

from __future__ import annotations

import os
import signal

# Two xdist workers on two cores, each with OpenBLAS's default of one thread per core,
# spin-wait on each other: scipy's SLSQP on the minimum test's twin took 56 s against
# 3.5 s with one thread each (what Dask's nanny sets for its workers too). Set before
# numpy is first imported, here and in the workers and subprocesses that inherit it.
for _threads in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_threads, "1")

import pytest  # noqa: E402

# A suite started in the background (``cmd &`` in a shell without job control) inherits
# Ctrl+C ignored, and so would every process a test starts: the tests that press Ctrl+C
# on a command would wait out its budget. Ctrl+C is given back its default here.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


@pytest.fixture(scope="session", autouse=True)
def compiled_kernels(tmp_path_factory):
    import fcntl

    import pliant as pl
    from pliant.errors import PliantError
    from pliant.models import first_run, rod3d
    from pliant.models.elastica2d import ShootingSolver
    from pliant.scene.distance import Obstacle

    # In a fresh clone both xdist workers compiled every kernel at once, the same ones
    # twice. The first to come compiles them ahead on both cores (the product's own
    # first-run path) while the other waits, then both load them from the cache.
    shared = tmp_path_factory.getbasetemp().parent / "kernels.lock"  # one per session
    with open(shared, "a") as lock:
        fcntl.flock(lock.fileno(), fcntl.LOCK_EX)
        for kind in ("3d", "2d"):
            if first_run.cold(kind):
                first_run.compile_ahead(cores=2, kind=kind)
        fcntl.flock(lock.fileno(), fcntl.LOCK_UN)

    part = pl.Part(length=1.0, bending_stiffness=1.0, mass_per_length=0.1,
                   outer_diameter=0.02)
    flat = pl.Problem(part, (pl.clamp(0.0), pl.grip(1.0, position=(0.7, 0.4), angle=1.0)),
                      gravity=(0.0, -9.81))
    try:  # the answer does not matter here, only that the kernels ran
        pl.solve(flat, solver=ShootingSolver(time_budget=3600.0))
    except PliantError:
        pass
    space = pl.Problem(part, (pl.clamp(0.0, (0.0, 0.0, 0.0)),
                              pl.grip(1.0, (0.7, 0.3, 0.2), tangent=(0.0, 1.0, 0.0),
                                      name="hand")),
                       gravity=(0.0, 0.0, -9.81),
                       obstacles=(Obstacle.sphere("ball", 0.1, (0.4, 0.0, -0.2)),))
    try:
        _ = rod3d.solve(space, solver=rod3d.RodSolver(elements=12, time_budget=3600.0)).stability
    except PliantError:
        pass
    yield


# The files that take longest, longest first: pytest-xdist hands whole files (--dist
# loadfile) to the two workers in collection order, so a long file collected last (the
# wheel's, alphabetically) ran alone at the end while the other worker idled. Longest
# first, the short ones fill the end. The rest keep their order.
LONGEST_FIRST = ("test_browser.py", "test_sequence.py", "test_clip_order.py", "test_wheel.py",
                 "test_viewer.py", "test_first_run.py", "test_lint.py", "test_harness_kbl.py",
                 "test_cli.py", "test_minimum.py", "test_coupled.py", "test_plan.py",
                 "test_combinations.py", "test_session.py", "test_settling.py",
                 "test_contact.py", "test_carry.py", "test_evaluation.py", "test_rod3d.py",
                 "test_study.py", "test_properties_3d.py", "test_scene_file.py")


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    rank = {name: k for k, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))
