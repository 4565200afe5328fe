"""Shared fixtures. Every build in the test session goes to a private cache under tmp, one
for the session's workers together under pytest-xdist (the cache is safe for concurrent
builds: tests/test_cache_security.py), so that a model one worker built is the other's too."""
from __future__ import annotations

import os

import pytest


@pytest.fixture(scope="session", autouse=True)
def _private_cache(tmp_path_factory):
    old = os.environ.get("GRASPING_SYM_CACHE")
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
