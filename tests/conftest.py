"""Shared fixtures."""
import pytest

from physlab import datasets


@pytest.fixture(scope="session")
def real_data():
    """The external real-data folder (``../shared/data`` or ``$PHYSLAB_EXTERNAL_DATA``);
    tests that use it skip with a reason when it is absent (it is always there in CI)."""
    root = datasets.external_data_dir()
    if root is None:
        pytest.skip("external data folder not found: set PHYSLAB_EXTERNAL_DATA or provide "
                    "<repo root>/../shared/data (AnimatedDrawings characters)")
    return root
