import os

import matplotlib

matplotlib.use("Agg")

# pytest-xdist runs one worker per core: one compute thread each, so workers do not fight
# over the cores (the sweep pool does the same for its workers)
if os.environ.get("PYTEST_XDIST_WORKER") and "NUMBA_NUM_THREADS" not in os.environ:
    os.environ["NUMBA_NUM_THREADS"] = "1"
