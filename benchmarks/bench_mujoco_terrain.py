"""Speed of the MuJoCo granular terrain on the demo hexapod, side by side in one run.

Per physics step of the demo (C legs on poppy LP, the demo's gait), the MuJoCo part
(``mj_step1`` + ``mj_step2``) and the terrain part are timed separately, for:

* ``compiled_loop`` (what the demo runs): ``GranularTerrain.run`` - MuJoCo's C ``mj_step1`` /
  ``mj_step2`` and the terrain kernel in one Numba loop, 10 steps per call with the gait's
  targets as the ctrl schedule; the phases are timed inside the loop (clock_gettime); the rest
  rule on (default), and the same with the plain explicit force (``stick=False``), with the
  float32 element loop, with the element law on whole runs of touching clusters instead of
  their gathered elements in the bed (``cluster_runs_no_gather``), and with the bed test per
  body only (no clusters: ``body_box_only``);
* ``compiled_loop_scalar_element_law``: ``compiled_loop`` in a child process compiled with
  LLVM's loop vectorizer off (``NUMBA_LOOP_VECTORIZE=0``): the element law as scalar code, as
  it ran until 2026-12-04, when a conditional load kept the loop from vectorizing;
* ``python_per_step``: the per-step Python path (``mj_step1``; ``terrain.apply``;
  ``mj_step2``; ``terrain.remove``; the gait line counts as MuJoCo's part), timed with
  perf_counter;
* ``baseline_per_body_evaluator_applyFT``: the straightforward code a user would write (per
  terrain body ``mj_objectVelocity`` + ``rft3d.Evaluator`` + ``mj_applyFT``), its wrench
  checked against the adapter's;
* ``mujoco_alone_compiled``: the robot in the same loop without the terrain (its floor contact
  is off, so it falls freely: MuJoCo's cost per step without contacts, for reference).

Statistic: per step, the steps the scheduler interrupted (step time > 3 x the median) are
left out (their fraction is reported), the mean of the others; the best (lowest) of REPEATS
runs. Also the simulated-to-wall-clock ratio of each loop (untimed run, wall clock, all
steps; the best of the repeats, all of them in the JSON). Everything again with two busy processes on the cores (``busy``).

Usage: python benchmarks/bench_mujoco_terrain.py [--quick] [--case NAME: one case, a JSON line]
(writes benchmarks/results/mujoco_terrain.json)
"""
from __future__ import annotations

import json
import os
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

os.environ.setdefault("MUJOCO_GL", "egl")
import mujoco  # noqa: E402

from terradyn import rft3d as r3  # noqa: E402
from terradyn.adapters import mujoco as am  # noqa: E402
from terradyn.adapters import mujoco_demo as md  # noqa: E402
from terradyn.io import atomic_write_text  # noqa: E402

QUICK = "--quick" in sys.argv
STEPS = 1500 if QUICK else 5000
WARM = 1000
REPEATS = 3
BLOCK = 10  # steps per compiled call, as in the demo
TARGET = 0.20


def _summary(step_times: np.ndarray, wall: float, steps: int, dt: float, **extra) -> dict:
    """Means per step (us) of the MuJoCo and terrain parts over the uninterrupted steps."""
    tot = step_times.sum(axis=1)
    keep = tot <= 3 * np.median(tot)
    mj, ter = step_times[keep].mean(axis=0) * 1e6
    return {"mujoco_us_per_step": float(mj), "terrain_us_per_step": float(ter),
            "terrain_share_of_step": float(ter / (mj + ter)), "steps": steps,
            "steps_kept_fraction": float(keep.mean()), "sim_to_wall": steps * dt / wall, "wall_s": wall, **extra}


def compiled(stick: bool = True, precision: str = "float64", terrain_on: bool = True,
             cluster: int | None = None, gather: bool = True) -> dict:
    dt = md.HEXAPOD.timestep
    out = {}
    for timed in (True, False):  # timed phases; then an untimed run for the wall clock
        model, data, terrain = md.build("c", "poppy LP", stick=stick)
        if precision != "float64" or cluster or not gather:
            keep = am.CLUSTER, am.GATHER
            am.CLUSTER, am.GATHER = cluster or keep[0], gather
            try:
                terrain = md.GranularTerrain(model, terrain.medium, bodies=md.terrain_bodies(), stick=stick,
                                             precision=precision)
            finally:
                am.CLUSTER, am.GATHER = keep
        terrain.run(data, WARM, ctrl=md.gait_schedule(0.0, WARM, dt), terrain=terrain_on)
        parts = []
        tic = time.perf_counter()
        for _ in range(0, STEPS, BLOCK):
            res = terrain.run(data, BLOCK, ctrl=md.gait_schedule(data.time, BLOCK, dt), timing=timed,
                              terrain=terrain_on)
            if timed:
                parts.append(res["step_times_s"])
        wall = time.perf_counter() - tic
        if timed:
            out = _summary(np.concatenate(parts), wall, STEPS, dt, elements=terrain.n_elements,
                           compiled=bool(res["compiled"]))
        else:
            out["sim_to_wall"], out["wall_s"] = STEPS * dt / wall, wall
    return out


def python_loop(baseline: bool = False) -> dict:
    model, data, terrain = md.build("c", "poppy LP")
    dt = model.opt.timestep
    ids = [int(b) for b in terrain.body_ids]
    evs = [r3.Evaluator(terrain.surfaces[model.body(b).name], terrain.medium) for b in ids]
    v6 = np.zeros(6)
    times = np.zeros((STEPS, 2))
    maxdiff = 0.0
    wall0 = time.perf_counter()
    for i in range(WARM + STEPS):
        if i == WARM:
            wall0 = time.perf_counter()
        a = time.perf_counter()
        data.ctrl[:] = md.gait_targets(data.time)
        mujoco.mj_step1(model, data)
        b = time.perf_counter()
        if baseline:
            data.qfrc_applied[:] = 0.0
            for bid, ev in zip(ids, evs):
                mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_BODY, bid, v6, 0)
                W = v6[:3]
                V = v6[3:] + np.cross(W, data.xpos[bid] - data.xipos[bid])  # at the body origin
                w = ev(data.xpos[bid], data.xquat[bid], V, W, terrain.surface, data.xipos[bid])
                mujoco.mj_applyFT(model, data, w[:3], w[3:], data.xipos[bid], bid, data.qfrc_applied)
                if i % 50 == 0:
                    terrain.stick = False
                    maxdiff = max(maxdiff, float(np.abs(w - terrain.wrenches(data)[ids.index(bid)]).max()))
                    terrain.stick = True
        else:
            terrain.apply(data)
        c = time.perf_counter()
        mujoco.mj_step2(model, data)
        if not baseline:
            terrain.remove(data)
        d = time.perf_counter()
        if i >= WARM:
            times[i - WARM] = (b - a) + (d - c), c - b
    wall = time.perf_counter() - wall0
    extra = {"max_abs_wrench_difference_vs_adapter_N": maxdiff} if baseline else {}
    return _summary(times, wall, STEPS, dt, elements=terrain.n_elements, **extra)


#: Numba cache of the child processes that compile with LLVM's loop vectorizer off (made in main).
SCALAR_CACHE: list[str] = []


def scalar_case() -> dict:
    """``compiled_loop`` in a child process whose LLVM loop vectorizer is off
    (NUMBA_LOOP_VECTORIZE=0, its own Numba cache): the element law as scalar code, as it ran
    before 2026-12-04 (a conditional load then kept the loop from vectorizing)."""
    if not SCALAR_CACHE:
        import tempfile
        SCALAR_CACHE.append(tempfile.mkdtemp(prefix="terradyn-scalar-numba-"))
    env = dict(os.environ, NUMBA_LOOP_VECTORIZE="0", NUMBA_CACHE_DIR=SCALAR_CACHE[0])
    r = subprocess.run([sys.executable, __file__, "--case", "compiled_loop"] + (["--quick"] if QUICK else []),
                       env=env, capture_output=True, text=True, check=True)
    return json.loads(r.stdout.strip().splitlines()[-1])


CASES = {
    "compiled_loop": lambda: compiled(True),
    "compiled_loop_scalar_element_law": scalar_case,
    "compiled_loop_plain_force": lambda: compiled(False),
    "compiled_loop_float32": lambda: compiled(True, "float32"),
    "compiled_loop_cluster_runs_no_gather": lambda: compiled(True, gather=False),
    "compiled_loop_body_box_only": lambda: compiled(True, cluster=10 ** 9, gather=False),
    "python_per_step": lambda: python_loop(False),
    "baseline_per_body_evaluator_applyFT": lambda: python_loop(True),
    "mujoco_alone_compiled": lambda: compiled(True, terrain_on=False),
}


def measure() -> dict:
    runs = {k: [] for k in CASES}
    for _ in range(REPEATS):  # interleaved, so a busy spell of the machine hits all cases alike
        for k, f in CASES.items():
            runs[k].append(f())
    best = {k: dict(min(v, key=lambda r: r["mujoco_us_per_step"] + r["terrain_us_per_step"]),
                    sim_to_wall=max(r["sim_to_wall"] for r in v),
                    sim_to_wall_of_repeats=[r["sim_to_wall"] for r in v]) for k, v in runs.items()}
    c, p, b = best["compiled_loop"], best["python_per_step"], best["baseline_per_body_evaluator_applyFT"]
    ratios = {"python_over_compiled_terrain_time": p["terrain_us_per_step"] / c["terrain_us_per_step"],
              "baseline_over_compiled_terrain_time": b["terrain_us_per_step"] / c["terrain_us_per_step"],
              "compiled_over_python_sim_to_wall": c["sim_to_wall"] / p["sim_to_wall"],
              "plain_over_rest_rule_terrain_time":
                  best["compiled_loop_plain_force"]["terrain_us_per_step"] / c["terrain_us_per_step"],
              "no_gather_over_gather_terrain_time":
                  best["compiled_loop_cluster_runs_no_gather"]["terrain_us_per_step"] / c["terrain_us_per_step"],
              "body_box_only_over_clusters_terrain_time":
                  best["compiled_loop_body_box_only"]["terrain_us_per_step"] / c["terrain_us_per_step"],
              "scalar_over_simd_terrain_time":
                  best["compiled_loop_scalar_element_law"]["terrain_us_per_step"] / c["terrain_us_per_step"],
              "float32_over_float64_terrain_time":
                  best["compiled_loop_float32"]["terrain_us_per_step"] / c["terrain_us_per_step"]}
    return {"load_average_1min_before": os.getloadavg()[0], "cases": best, "ratios": ratios,
            "verdict": {k: ("met" if v["terrain_share_of_step"] <= TARGET else "not met")
                        for k, v in best.items() if k != "mujoco_alone_compiled"}}


def _print(name: str, r: dict) -> None:
    print(f"{name} (load average before {r['load_average_1min_before']:.1f})")
    for k, v in r["cases"].items():
        share = "" if k == "mujoco_alone_compiled" else \
            f"share {v['terrain_share_of_step'] * 100:5.1f} % ({r['verdict'][k]}, target <= {TARGET * 100:.0f} %)  "
        print(f"  {k:38s} MuJoCo {v['mujoco_us_per_step']:6.2f} us  terrain {v['terrain_us_per_step']:6.2f} us  "
              f"{share}sim/wall {v['sim_to_wall']:6.1f}  (kept {v['steps_kept_fraction'] * 100:.0f} % of steps)")
    for k, v in r["ratios"].items():
        print(f"    {k}: {v:.2f}")


def main():
    if "--case" in sys.argv:  # one case, its result as a JSON line (the scalar child process)
        print(json.dumps(CASES[sys.argv[sys.argv.index("--case") + 1]]()))
        return
    out = Path(__file__).parent / "results" / "mujoco_terrain.json"
    out.parent.mkdir(exist_ok=True)
    rows = {"idle": measure()}
    _print("as found", rows["idle"])
    busy = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(2)]
    try:
        time.sleep(1.0)
        rows["busy"] = measure()
    finally:
        for p in busy:
            p.kill()
            p.wait()
    _print("two busy processes on the cores", rows["busy"])
    atomic_write_text(out, json.dumps({
        "machine": {"cpu": platform.processor() or platform.machine(), "cores": os.cpu_count(),
                    "python": platform.python_version(), "mujoco": mujoco.__version__,
                    "note": "shared machine: other developers' work runs on the same 2 cores (see the load "
                            "averages); 'busy' adds two busy-loop processes"},
        "command": "python benchmarks/bench_mujoco_terrain.py" + (" --quick" if QUICK else ""),
        "robot": "demo hexapod (terradyn.adapters.mujoco_demo), C legs, poppy LP, 7 terrain bodies, gait of the demo",
        "steps": STEPS, "warm_up_steps": WARM, "steps_per_compiled_call": BLOCK, "repeats": REPEATS,
        "statistic": "mean over the steps not interrupted by the scheduler (step time <= 3 x median); "
                     "best of the repeats (lowest MuJoCo + terrain time); sim_to_wall from untimed runs, "
                     "the best of the repeats",
        "target_terrain_share_of_step": TARGET, "rows": rows}, indent=1) + "\n")
    print(f"wrote {out}")
    if SCALAR_CACHE:  # the child processes' cache, made by this run
        import shutil
        shutil.rmtree(SCALAR_CACHE[0], ignore_errors=True)


if __name__ == "__main__":
    main()
