import os

import matplotlib

matplotlib.use("Agg")

# pytest-xdist runs one worker per core: one compute thread each, so workers do not fight
# over the cores (the sweep pool does the same for its workers)
if os.environ.get("PYTEST_XDIST_WORKER") and "NUMBA_NUM_THREADS" not in os.environ:
    os.environ["NUMBA_NUM_THREADS"] = "1"


import pytest  # noqa: E402


@pytest.fixture(autouse=True)
def _close_figures():
    """The plotting functions return their figure to the caller (who may keep drawing on it):
    close what a test leaves open, so one worker does not pile up hundreds of figures."""
    yield
    import matplotlib.pyplot as plt

    plt.close("all")
