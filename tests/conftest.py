"""Shared fixtures. Every build in the test session goes to a private cache under tmp, one
for the session's workers together under pytest-xdist (the cache is safe for concurrent
builds: tests/test_cache_security.py), so that a model one worker built is the other's too.

The session compiles at no optimisation (``GRASPING_SYM_OPT=none``, -O0: gcc was most of the
suite's time, and -O0 compiles the models' C about 4.5 times faster than -Og): the numbers are the
full level's, bit for bit (``test_compiled_runtime.py::test_every_level_computes_what_a_full_build_does``,
which builds each)."""
from __future__ import annotations

import os

import pytest

# One thread per worker for OpenMP (IPOPT's MUMPS, which CasADi bundles): its idle threads spin,
# and each worker already has a core of its own. The optimal-control tests burned twice their
# wall time in CPU, a core taken from the other worker (scripts/test.sh also sets OpenBLAS's,
# which NumPy has loaded before this file runs).
os.environ.setdefault("OMP_NUM_THREADS", "1")


@pytest.fixture(scope="session", autouse=True)
def _private_cache(tmp_path_factory):
    old = os.environ.get("GRASPING_SYM_CACHE")
    old_level = os.environ.get("GRASPING_SYM_OPT")
    os.environ["GRASPING_SYM_OPT"] = "none"
    if os.environ.get("PYTEST_XDIST_WORKER"):  # the workers' base directories share a parent
        root = tmp_path_factory.getbasetemp().parent / "gs-cache"
        root.mkdir(exist_ok=True)
    else:
        root = tmp_path_factory.mktemp("gs-cache")
    os.environ["GRASPING_SYM_CACHE"] = str(root)
    yield
    if old is None:
        os.environ.pop("GRASPING_SYM_CACHE", None)
    else:
        os.environ["GRASPING_SYM_CACHE"] = old
    if old_level is None:
        os.environ.pop("GRASPING_SYM_OPT", None)
    else:
        os.environ["GRASPING_SYM_OPT"] = old_level


@pytest.fixture(scope="session")
def paper2d_model(_private_cache):
    import grasping_sym as gs

    return gs.build(gs.scenes.paper2d())


@pytest.fixture(scope="session")
def paper3d_model(_private_cache):
    import grasping_sym as gs

    return gs.build(gs.scenes.paper3d())


@pytest.fixture(scope="session")
def paper2d_result(paper2d_model):
    return paper2d_model.simulate(
        3.0, rtol=1e-10, atol=1e-12,
        t_eval=None,
    )


#: The heaviest test files (their builds, mostly), longest first: collected before the others so
#: that pytest-xdist's workers (one file at a time, ``--dist loadfile``) start them first and
#: finish together instead of one worker running a long file alone at the end. A file not
#: named keeps its place after these; the order within a file is kept.
HEAVY_FIRST = (
    "test_atlas.py", "test_planar_free.py", "test_docs.py", "test_sweep.py", "test_examples_control.py",
    "test_planar_multifinger.py", "test_layers.py", "test_cache_security.py", "test_runtime_guards.py",
    "test_grasp_modes.py", "test_cli_plots3d.py", "test_compiled_vs_symbolic.py", "test_modes.py",
    "test_interrupts.py", "test_compiled_runtime.py", "test_reference3d_paper.py", "test_contact3d.py",
    "test_generated_golden.py", "test_hard_cases.py", "test_spatial.py", "test_hands_urdf.py",
    "test_paper3d.py",
)


def pytest_collection_modifyitems(session, config, items):
    rank = {name: k for k, name in enumerate(HEAVY_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))  # stable: files stay whole
