"""The 3D SPH's GPU path (terradyn.sph.gpu3d) against its CPU kernels.

Without a GPU the checks run in a subprocess under Numba's CUDA simulator
(NUMBA_ENABLE_CUDASIM=1, set before numba.cuda is imported; one subprocess for all of them);
with TERRADYN_GPU_TEST=device they run on the GPU. Where numba-cuda is installed (the 'gpu'
extra) the kernels are also compiled to PTX for sm_90, which the simulator does not do.
"""
from __future__ import annotations

import textwrap

import numpy as np
import pytest
from gpu_checks import compile_ptx_checks, run_checks

from terradyn.errors import InputError

_CHECKS = textwrap.dedent(r'''
    import json, math, sys
    sys.setswitchinterval(1e-5)  # the simulator's thread barriers: much faster
    import numpy as np
    from numba import config
    import terradyn.sph.plate3d as P
    from terradyn.sph.state import SPHConfig

    steps = int(sys.argv[1])
    out = {"device": not config.ENABLE_CUDASIM}

    def rel(a, b):
        return float(np.abs(a - b).max() / max(np.abs(a).max(), 1e-300))

    # 1. a plate pushed into a bed with a y = 0 mirror (ghosts); between two blocks of steps
    #    the list reference is moved, so the second block rebuilds through the device's
    #    displacement check
    res = {}
    for be in ("cpu", "gpu"):
        cfg = SPHConfig(dx=6e-3, settle_time=0.0, backend=be)
        sc = P.plate_scene("3 mm glass CP", config=cfg, half_x=0.015, half_y=0.012,
                           depth=0.015, mirror_x=False, z0=-0.002)
        s = P.Solver3D(sc, plate_speed=0.2)
        pose = np.zeros((2 * steps, 6))
        pose[:, 1] = -0.002 - 0.2 * s.dt * np.arange(2 * steps)
        pose[:, 4] = -0.2
        f1 = s.advance(pose[:steps], np.zeros(steps))
        s.pb[:] += 1.0
        f2 = s.advance(pose[steps:], np.zeros(steps))
        res[be] = (np.concatenate([f1, f2]), s)
    (fc, c), (fg, g) = res["cpu"], res["gpu"]
    n = c.nr
    out["plate"] = {"particles": n, "ghosts": [int(c.ip[P.I_NG]), int(g.ip[P.I_NG])],
                    "builds": [int(c.ip[P.I_BUILDS]), int(g.ip[P.I_BUILDS])],
                    "Fz_last": float(fc[-1, 2]), "rel_F": rel(fc, fg),
                    "rel_pos": rel(c.pos[:n], g.pos[:n]), "rel_sig": rel(c.sig[:n], g.sig[:n]),
                    "rel_vel": rel(c.vel[:n], g.vel[:n]), "steps": [c.step_count, g.step_count]}

    # 2. a C leg (curved markers, arc side test) turning in a plane-strain slab
    res = {}
    for be in ("cpu", "gpu"):
        cfg = SPHConfig(dx=8e-3, settle_time=0.0, backend=be)
        sc = P.plate_scene("poppy LP", config=cfg, length=0.0762, width=0.0254,
                           thickness=0.0064, slab=4, half_x=0.045, depth=0.03, mirror_x=False,
                           pose=(0.0, 0.075 - 0.0381, -0.5 * math.pi),
                           curvature=P.leg_curvature("c"))
        s = P.Solver3D(sc, plate_speed=0.1)
        om = -2.0
        ph = -0.5 * math.pi + om * s.dt * np.arange(steps)
        cx, cz = 0.0381 * np.cos(ph), 0.075 + 0.0381 * np.sin(ph)  # hip 7.5 cm up
        pose = np.stack([cx, cz, ph, -om * (cz - 0.075), om * cx, np.full(steps, om)], -1)
        res[be] = (s.advance(pose, np.zeros(steps)), s)
    (fc, c), (fg, g) = res["cpu"], res["gpu"]
    n = c.nr
    out["leg"] = {"particles": n, "arc": int(c.ip[P.I_ARC]), "F_last": fc[-1].tolist(),
                  "rel_F": rel(fc, fg), "rel_pos": rel(c.pos[:n], g.pos[:n]),
                  "rel_sig": rel(c.sig[:n], g.sig[:n])}

    # 3. a grain below the floor is lost and counted; 4. a grain faster than sound is an
    #    instability named with its step and particle
    cfg = SPHConfig(dx=8e-3, settle_time=0.0, backend="gpu")
    sc = P.plate_scene("poppy LP", config=cfg, half_x=0.03, half_y=0.02, depth=0.02,
                       with_plate=False)
    s = P.Solver3D(sc)
    i = int(s.soil[0])
    s.pos[i, 2] = -1.0
    s.advance(np.zeros((1, 6)), np.zeros(1))
    out["lost"] = [s.lost, int(s.kind[i]), float(s.pos[i, 0])]
    j = int(s.soil[3])
    xj = s.pos[j].copy()
    s.vel[j, 2] = 1e4
    try:
        s.advance(np.zeros((1, 6)), np.zeros(1))
        out["unstable"] = None
    except Exception as e:
        k = int(s.ip[P.I_BAD])  # the particle named: j or one its speed upset at once
        out["unstable"] = {"type": type(e).__name__, "msg": str(e), "particle": k,
                           "near": bool(np.linalg.norm(s.pos[k] - xj) < 3 * s.h)}
    print("RESULT " + json.dumps(out))
''')


def _run_checks() -> dict:
    """All GPU checks, in one subprocess under the CUDA simulator (or on a real device)."""
    return run_checks(_CHECKS, 3)


def test_gpu3d_under_the_cuda_simulator_matches_the_cpu_kernels():
    """One subprocess: a pushed plate with mirror ghosts and a list rebuild mid-run, a curved
    leg turning, a lost grain and an instability, each against the CPU path."""
    sim = _run_checks()
    pl = sim["plate"]
    assert pl["ghosts"][0] == pl["ghosts"][1] > 0  # the y = 0 mirror is in play
    assert pl["builds"] == [2, 2]  # the second block rebuilt its lists on both paths
    assert pl["steps"][0] == pl["steps"][1]
    assert pl["Fz_last"] > 0.0  # the plate pushes into the bed and is resisted
    for k in ("rel_F", "rel_pos", "rel_sig", "rel_vel"):
        assert pl[k] < 1e-9, (k, pl[k])  # atomics reorder sums: rounding only
    lg = sim["leg"]
    assert lg["arc"] == 1 and np.abs(lg["F_last"]).max() > 0.0
    for k in ("rel_F", "rel_pos", "rel_sig"):
        assert lg[k] < 1e-9, (k, lg[k])
    lost, kind, x = sim["lost"]
    assert lost == 1 and kind == 3 and x > 100.0  # LOST, parked far away
    u = sim["unstable"]
    assert u is not None and u["type"] == "InputError"
    assert "went unstable at step 2" in u["msg"] and f"particle {u['particle']} at" in u["msg"]
    assert u["near"]


_PTX = textwrap.dedent(r'''
    import types
    import numpy as np
    from numba import cuda, typeof
    import numba.cuda.dispatcher as disp
    if not cuda.is_available():  # device functions ask the current device for its arch
        disp.get_current_device = lambda: types.SimpleNamespace(compute_capability=(9, 0))
    import terradyn.sph.plate3d as P
    import terradyn.sph.gpu3d as G
    from terradyn.sph.state import SPHConfig
    sc = P.plate_scene("3 mm glass CP", config=SPHConfig(dx=8e-3, settle_time=0.0),
                       half_x=0.03, half_y=0.02, depth=0.02)
    s = P.Solver3D(sc)
    d = {k: np.ascontiguousarray(getattr(s, k)) for k in G.STATE + G.CONST}
    a = lambda *ks: tuple(d[k] for k in ks)
    one = np.zeros(1)
    args = {
        "_k_pose": (np.zeros((2, 6)), 1, d["fp"]),
        "_k_place": a("pos", "vel", "wn", "bo", "bn", "lidx", "fp"),
        "_k_sides": a("pos", "kind", "side", "fp", "ip"),
        "_k_disp2": (*a("pos", "pb", "kind"), 1, one),
        "_k_ghosts": a("pos", "vel", "gv", "rho", "mass", "sig", "kind", "nz", "wn", "dcl", "grd",
                       "side", "src", "gs", "go", "ip"),
        "_k_zero_rows": (d["bacc"], 1),
        "_k_boundary": (*a("pos", "vel", "rho", "sig", "kind", "wn", "dcl", "sb", "sbo", "wsb"),
                        True, *a("bacc", "fp", "ip")),
        "_k_boundary_fin": (*a("vel", "gv", "sig", "kind", "bacc"), 1),
        "_k_strain": a("pos", "vel", "gv", "rho", "mass", "kind", "wn", "dcl", "side", "ss", "sso",
                       "sb", "sbo", "fss", "fsb", "lg", "fp", "ip"),
        "_k_dp": (*a("rho", "sig", "kind", "lg", "fp"), 1),
        "_k_psig": (*a("rho", "sig", "psig"), 1),
        "_k_accel": a("pos", "vel", "rho", "mass", "psig", "kind", "nz", "wn", "dcl", "grd", "ss",
                      "sso", "sb", "sbo", "fss", "fsb", "acc", "cont", "fp", "ip"),
        "_k_kick": (*a("pos", "vel", "mass", "rho", "sig", "kind", "acc", "cont"), 1.0,
                    *a("fp", "ip"), np.zeros((2, 3)), 1, np.zeros(2, np.int64)),
    }
    assert set(args) == {k for k in vars(G) if k.startswith("_k_")}
    for name, x in args.items():
        ptx, _ = cuda.compile_ptx(getattr(G, name).py_func, tuple(typeof(v) for v in x),
                                  cc=(9, 0))
        assert ".entry" in ptx, name
        if name != "_k_pose":  # its cos / sin keep libdevice's slow-path call
            assert "call." not in ptx, name  # device functions inlined
        print(name, "ok")
''')


def test_gpu3d_kernels_compile_for_hopper():
    """Real CUDA compilation of every 3D kernel to PTX for sm_90 (type inference, lowering,
    NVVM), which the simulator does not do; needs numba-cuda (the 'gpu' extra), no GPU."""
    assert compile_ptx_checks(_PTX).count(" ok") == 13


def test_only_the_pair_sums_become_atomic():
    """The one-source rewrite: in the device copies, every += / -= into the arrays that
    several threads add into (bacc, lg, acc) is an atomic add, and nothing else changes."""
    from terradyn.sph import gpu3d as G
    from terradyn.sph import plate3d as P

    counts = {name: G._atomic_source(getattr(P, name))[1] for name in G.ONE_SOURCE}
    # _boundary_one: weight, stress (loop), velocity x 3, gravity term; _add_grad: 10 sums;
    # _accel_one: the partner's 3 and the particle's own 3
    assert counts == {**dict.fromkeys(G.ONE_SOURCE, 0), "_boundary_one": 6, "_add_grad": 10,
                      "_accel_one": 6}
    src, _ = G._atomic_source(P._accel_one)
    assert "acc[a, 3] = f3x" in src  # a particle's own force on the plate: a plain store
    assert "@" not in src.split("def ")[0]  # decorators dropped


def test_3d_gpu_backend_without_a_gpu_is_a_clear_error(monkeypatch):
    from numba import cuda

    from terradyn.sph import plate3d as P
    from terradyn.sph.state import SPHConfig

    monkeypatch.setattr(cuda, "is_available", lambda: False)
    kw = dict(half_x=0.03, half_y=0.02, depth=0.02, with_plate=False)
    with pytest.raises(InputError, match="no CUDA GPU available: use backend='cpu'"):
        P.Solver3D(P.plate_scene("poppy LP", config=SPHConfig(dx=8e-3, backend="gpu"), **kw))
    s = P.Solver3D(P.plate_scene("poppy LP", config=SPHConfig(dx=8e-3, backend="auto"), **kw))
    assert s.backend == "cpu"


def test_cli_leg3d_backend_option(monkeypatch, capsys):
    from numba import cuda

    from terradyn.cli import main

    monkeypatch.setattr(cuda, "is_available", lambda: False)
    assert main(["sph", "leg3d", "--medium", "poppy LP", "--backend", "gpu"]) == 2
    err = capsys.readouterr().err
    assert "no CUDA GPU available" in err and len(err.strip().splitlines()) == 1
