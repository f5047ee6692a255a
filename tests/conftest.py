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
