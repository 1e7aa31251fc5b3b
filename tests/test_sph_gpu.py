"""The GPU backend of the SPH solver (terradyn.sph.gpu), run here in Numba's CUDA simulator.

The simulator must be switched on before numba.cuda is first imported, so the GPU checks
run in a subprocess with NUMBA_ENABLE_CUDASIM=1 (one subprocess for all of them: the
simulator runs every GPU thread as a Python thread and is slow). On a machine with an NVIDIA
GPU the same checks run on the device with ``TERRADYN_GPU_TEST=device`` (see docs/sph.md).
The pytest process itself never imports the simulator.
"""
from __future__ import annotations

import textwrap

import numpy as np
import pytest
from gpu_checks import compile_ptx_checks, run_checks

from terradyn.errors import InputError
from terradyn.sph import SPHConfig, scenes, solver

_CHECKS = textwrap.dedent(r'''
    import json, math, sys
    sys.setswitchinterval(1e-5)  # the simulator's thread barriers: much faster
    import numpy as np
    import terradyn as td
    from terradyn.sph import SPHConfig, SPHInstabilityError, kernels as K, scenes, solver
    from terradyn.sph import gpu
    from terradyn.units import DEG

    out = {"device": not gpu.SIM}

    # 1. binning: the device's counting sort gives the CPU's cell lists exactly (a few
    #    cells; and enough cells that the scan of the block sums works in chunks)
    rng = np.random.default_rng(1)
    binning = []
    for n, ncx, ncz in ((200, 9, 5), (300, 110, 100)):
        x, z = rng.uniform(-0.1, 1.1, n), rng.uniform(-0.1, 0.6, n)  # some outside: clamped
        cs = np.zeros(ncx * ncz + 1, np.int64)
        ci = np.zeros(n, np.int64)
        K.bin_particles(x, z, 0.0, 0.0, ncx, ncx, ncz, cs, ci)
        gs, gi = gpu.bin_particles(x, z, 0.0, 0.0, ncx, ncx, ncz)
        binning.append([bool(np.array_equal(gs, cs)), bool(np.array_equal(gi, ci)),
                        int(gpu.DeviceBins(n, ncx, ncz).nblk)])
    out["binning"] = binning

    # 2. a short leg intrusion on both backends
    leg = td.flat_leg(length=0.04)
    traj = td.Rotation(omega=5.0, hip_height=0.02, theta_start=-45 * DEG,
                       theta_end=-30 * DEG, n_theta=4).trajectory()

    def scene(backend):  # side walls 2 cm apart and grain-leg friction: compared too
        return scenes.leg_scene(leg, traj, 0, bed_width=0.07, bed_depth=0.02,
                                config=SPHConfig(dx=5e-3, settle_time=2e-4, wall_layers=2,
                                                 backend=backend, channel_width=0.02,
                                                 leg_friction=0.2))

    nsteps = int(sys.argv[1])
    res = {}
    for b in ("cpu", "gpu"):
        s = solver.Solver(scene(b))
        f = [s.step() for _ in range(nsteps)]
        s.sync_to_host()  # the GPU backend's arrays here are current after this (CPU: no-op)
        sid = s.sidx
        res[b] = {"backend": s.backend_name, "n": s.n, "soil": len(sid), "F": np.array(f),
                  "x": s.x[sid], "z": s.z[sid], "vx": s.vx[sid], "rho": s.rho[sid],
                  "sxx": s.sxx[sid], "szz": s.szz[sid], "sxz": s.sxz[sid], "syy": s.syy[sid],
                  "cell_start": s.cell_start, "cell_index": s.cell_index}
        if b == "gpu":
            # state_dict / load_state round trip: the host copy goes back to the device
            st = {k: np.array(v, copy=True) for k, v in s.state_dict().items()}
            f1 = [s.step() for _ in range(2)]
            s.load_state(st)
            f2 = [s.step() for _ in range(2)]
            f1, f2 = np.array(f1), np.array(f2)  # equal but for the order of the atomic sums
            out["reload_rel"] = float(np.max(np.abs(f1 - f2)) / np.max(np.abs(f1)))
    c, g = res["cpu"], res["gpu"]
    out["backends"] = [c["backend"], g["backend"]]
    out["particles"] = [c["n"], c["soil"]]
    rel = {}
    for k in ("F", "x", "z", "vx", "rho", "sxx", "szz", "sxz", "syy"):
        rel[k] = float(np.max(np.abs(g[k] - c[k])) / max(np.max(np.abs(c[k])), 1e-300))
    out["rel"] = rel
    out["cells_equal"] = bool(np.array_equal(c["cell_start"], g["cell_start"])
                              and np.array_equal(c["cell_index"], g["cell_index"]))
    out["Fz_last"] = float(c["F"][-1][1])

    # 3. an instability on the GPU path: reported with step and particle
    s = solver.Solver(scenes.bed_scene(width=0.03, depth=0.015, dx=5e-3, settle_time=0.0,
                                       wall_layers=2, backend="gpu"))
    s.step()
    s.sync_to_host()
    i = int(s.sidx[3])
    x0, z0 = s.x.copy(), s.z.copy()
    s.szz[i] = np.nan  # an edit on the host: goes to the device before the next step
    try:
        s.step()
        out["unstable"] = None
    except SPHInstabilityError as e:
        p = e.particle
        out["unstable"] = {"step": e.step, "near": bool(math.hypot(x0[p] - x0[i], z0[p] - z0[i])
                                                        < 2 * s.h), "msg": str(e)}

    # 4. a grain outside the container is dropped on the device
    s = solver.Solver(scenes.bed_scene(width=0.03, depth=0.015, dx=5e-3, settle_time=0.0,
                                       wall_layers=2, backend="gpu"))
    n0 = len(s.sidx)
    i = int(s.sidx[0])
    s.x[i], s.z[i] = 0.0, -0.2
    s.step()
    s.drop_lost()
    s.sync_to_host()
    out["dropped"] = [int(s.lost), n0 - len(s.sidx), int(s.kind[i]), float(s.x[i])]

    # 5. run() on the GPU backend: force record and snapshots
    r = solver.run(scene("gpu"), 3e-4, snapshot_times=[1e-4])
    out["run"] = {"steps": r.steps, "records": len(r.Fz), "snaps": len(r.snapshots),
                  "finite": bool(np.isfinite(r.Fz).all())}
    print("RESULT " + json.dumps(out))
''')


def _run_checks() -> dict:
    """All GPU checks, in one subprocess under the CUDA simulator (or on a real device)."""
    return run_checks(_CHECKS, 12)


def test_gpu_backend_under_the_cuda_simulator():
    """One test (one slow subprocess, whatever pytest-xdist does with the tests): binning,
    a leg intrusion (in a channel with side-wall friction) against the CPU backend, state
    round trip, instability, lost grains,
    run()."""
    sim = _run_checks()
    # the device's counting sort gives the CPU's cell lists exactly
    (few_s, few_i, _), (many_s, many_i, nblk) = sim["binning"]
    assert few_s and few_i and many_s and many_i
    if not sim["device"]:
        assert nblk > 32  # the one-block scan of the block sums ran in chunks
    # a short leg intrusion: same positions, stresses, leg force as the CPU backend
    assert sim["backends"] == ["cpu", "gpu"]
    n, soil = sim["particles"]
    assert 100 <= n <= 300 and soil > 30
    assert sim["Fz_last"] != 0.0  # the leg is in the bed: the force is compared too
    for k, r in sim["rel"].items():
        assert r < 1e-9, (k, r)
    assert sim["cells_equal"]  # cells sorted by id: the same neighbour order as the CPU's
    assert sim["reload_rel"] < 1e-12  # state_dict / load_state round trip
    # an instability on the GPU path names step and particle
    u = sim["unstable"]
    assert u is not None and u["step"] == 1 and u["near"], u
    assert "unstable at step 1" in u["msg"]
    # grains that leave the container are dropped on the device
    lost, fewer, kind, x = sim["dropped"]
    assert lost == 1 and fewer == 1 and kind == 3 and x > 100.0
    # run() records forces and snapshots
    r = sim["run"]
    assert r["steps"] > 0 and r["records"] > 0 and r["snaps"] == 1 and r["finite"], r


_PTX = textwrap.dedent(r'''
    import types
    import numpy as np
    from numba import cuda, typeof
    import numba.cuda.dispatcher as disp
    if not cuda.is_available():  # device functions ask the current device for its arch
        disp.get_current_device = lambda: types.SimpleNamespace(compute_capability=(9, 0))
    from terradyn.sph import gpu as G
    from terradyn.sph.neighbours import neighbour_list
    from terradyn.sph.physics import Gravity, Grid, StrainPar
    from terradyn.sph.source import SOURCES
    n, nc = 100, 50
    S, srt, srtk = np.zeros((18, n)), np.zeros((11, n)), np.zeros((3, n))
    kind, bad, fleg, acc = np.zeros(n, np.int8), np.zeros(n, np.int8), np.zeros((n, 3)), np.zeros(4)
    i32 = lambda m: np.zeros(m, np.int32)
    nb = neighbour_list(n, 1.3)
    grid = Grid(1.0, 1.0, 1.0, 1.0, 3, 4)
    par_s = StrainPar(*grid, *(1.0,) * 10, True, 0.0, 0.0, 1.0, 1.0)
    par_a = SOURCES["_accel_par"](*(1.0,) * 4, True, *(1.0,) * 13, 3, 4, 1.0, 1.0, 1.0, 0.0, -1.0)
    args = {
        "_k_count": (S, 1.0, 1.0, 1.0, 3, 4, i32(nc), i32(n), i32(n)),
        "_k_scan_blocks": (i32(nc), i32(nc), i32(4), i32(64), 1),
        "_k_scan_sums": (i32(4), 4, i32(256), acc),
        "_k_scan_finish": (i32(nc), i32(4), i32(nc + 1), 256),
        "_k_scatter": (i32(n), i32(n), i32(nc + 1), i32(n)),
        "_k_sort_cells": (i32(nc + 1), i32(n)),
        "_k_place": (S, i32(10), np.zeros((4, 10)), *(1.0,) * 10),
        "_k_boundary": (S, kind, i32(10), Gravity(1.0, 1.0), grid, i32(nc + 1), i32(n), True, *nb[:2],
                        True),
        "_k_gather": (i32(n), S, kind, srt, srtk),
        "_k_regather": (i32(n), S, kind, srt),
        "_k_strain": (srt, srtk, i32(n), i32(nc + 1), S, *nb, par_s),
        "_k_accel": (srt, srtk, i32(n), i32(nc + 1), S, fleg, bad, *nb[2:], par_a, acc),
        "_k_drop": (S, kind, fleg, 1.0, 1.0, 1.0, i32(1)),
        "_k_disp": (S, np.zeros(n), np.zeros(n), np.zeros(1), acc),
        "_k_mark": (S, np.zeros(n), np.zeros(n)),
    }
    for name, a in args.items():
        ptx, _ = cuda.compile_ptx(getattr(G, name).py_func, tuple(typeof(x) for x in a),
                                  cc=(9, 0))
        assert ".entry" in ptx and "call." not in ptx, name  # device functions inlined
        print(name, "ok")
''')


def test_gpu_kernels_compile_for_hopper():
    """Real CUDA compilation (type inference, lowering, NVVM) to PTX for sm_90, which the
    simulator does not do; needs numba-cuda with its CUDA toolkit wheels, no GPU."""
    assert compile_ptx_checks(_PTX).count(" ok") == 15


# ------------------------------------------------------------------------ in-process, no GPU
def test_backend_is_validated():
    with pytest.raises(InputError, match="backend.*'cpu', 'gpu', 'auto'"):
        SPHConfig(backend="tpu")
    assert SPHConfig().backend == "cpu"


def test_gpu_backend_without_a_gpu_is_a_clear_error(monkeypatch):
    from numba import cuda

    monkeypatch.setattr(cuda, "is_available", lambda: False)
    sc = scenes.bed_scene(width=0.03, depth=0.015, dx=5e-3, settle_time=0.0, backend="gpu")
    with pytest.raises(InputError, match="no CUDA GPU available: use backend='cpu'"):
        solver.Solver(sc)
    s = solver.Solver(scenes.bed_scene(width=0.03, depth=0.015, dx=5e-3, settle_time=0.0,
                                       backend="auto"))
    assert s.backend_name == "cpu"
    s.step()
    assert np.isfinite(s.x).all()


def test_cli_backend_option(monkeypatch, capsys):
    from numba import cuda

    from terradyn.cli import main

    monkeypatch.setattr(cuda, "is_available", lambda: False)
    args = ["sph", "run", "--quick", "--theta-start-deg", "-135", "--theta-end-deg", "-100",
            "--n-theta", "4"]
    assert main(args + ["--backend", "gpu"]) == 2
    assert "no CUDA GPU available" in capsys.readouterr().err
    assert main(args + ["--backend", "auto"]) == 0


def test_checkpoint_key_ignores_the_backend():
    a = scenes.bed_scene(width=0.03, depth=0.015, dx=5e-3, backend="cpu")
    b = scenes.bed_scene(width=0.03, depth=0.015, dx=5e-3, backend="auto")
    assert solver.scene_key(a) == solver.scene_key(b)
