"""Fixtures shared by the tests (the paths themselves are in helpers.py)."""

import pytest
from helpers import REPO, require_shared_data


@pytest.fixture(scope="session")
def repo():
    return REPO


@pytest.fixture(scope="session")
def shared_data():
    """The shared real data; a test that needs it fails (never skips) without it."""
    return require_shared_data()


def pytest_collection_modifyitems(config, items):
    """The long fuzzing runs only when asked for (``-m fuzz_long``)."""
    if "fuzz_long" in (config.getoption("markexpr") or ""):
        return
    keep = [i for i in items if i.get_closest_marker("fuzz_long") is None]
    if len(keep) < len(items):
        config.hook.pytest_deselected(items=[i for i in items if i not in keep])
        items[:] = keep
