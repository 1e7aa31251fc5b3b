"""Shared by the GPU tests: run a script of checks in a subprocess, under Numba's CUDA
simulator (NUMBA_ENABLE_CUDASIM=1, which must be set before numba.cuda is first imported,
hence the subprocess), or on a GPU with TERRADYN_GPU_TEST=device. The script gets the number
of steps as its first argument and prints one line ``RESULT <json>``."""
from __future__ import annotations

import json
import os
import subprocess
import sys


def run_checks(code: str, sim_steps: int, device_steps: int = 40) -> dict:
    """The subprocess compiles into a Numba cache of its own (a temporary folder): a fresh
    CI clone once segfaulted in the CPU kernels here, loading the shared cache that the test
    workers were writing at the same time, and ran with a fresh one."""
    import shutil
    import tempfile

    env = dict(os.environ)
    device = os.environ.get("TERRADYN_GPU_TEST") == "device"
    if not device:
        env["NUMBA_ENABLE_CUDASIM"] = "1"
    cache = tempfile.mkdtemp(prefix="terradyn-gpu-test-cache-")
    env["NUMBA_CACHE_DIR"] = cache
    try:
        p = subprocess.run([sys.executable, "-c", code,
                            str(device_steps if device else sim_steps)],
                           env=env, capture_output=True, text=True, timeout=900)
    finally:
        shutil.rmtree(cache, ignore_errors=True)
    assert p.returncode == 0, f"rc {p.returncode}\n{p.stderr[-3000:]}\n{p.stdout[-1000:]}"
    line = [ln for ln in p.stdout.splitlines() if ln.startswith("RESULT ")][-1]
    return json.loads(line[len("RESULT "):])


def compile_ptx_checks(code: str) -> str:
    """Run a script that compiles kernels to PTX (real CUDA compilation: type inference,
    lowering, NVVM, which the simulator does not do) outside the simulator; needs numba-cuda
    (the 'gpu' extra), no GPU: skips the test where it is absent. Returns its stdout."""
    import importlib.util

    import pytest

    if importlib.util.find_spec("numba_cuda") is None:
        pytest.skip("numba-cuda is not installed (the 'gpu' extra)")
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_ENABLE_CUDASIM"}
    p = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                       timeout=600)
    assert p.returncode == 0, p.stderr[-3000:]
    return p.stdout
