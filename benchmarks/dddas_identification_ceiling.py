"""What limits terrain identification at 30 % of the stroke (issue 13): the exact Bayes posterior
(quadrature, :meth:`TerrainFilter.on_grid`) on the forecast study's trials, with the study's
sensors and with other sensor sets or a known strength, to show where the information is.

Per leg, trials drawn as in ``terradyn dddas forecast`` (20 per medium, 5 % noise, bias 2 %,
k ~ N(1, 0.1^2), seed 0 per leg: ``forecast.make_trial``) and these variants of the observer (the trial
data are the same; only what the observer reads or knows changes):
* ``study``: the study's channels (legs Fx, Fz, torque; foot Fx, Fz, load cell at 10 cm);
* ``all_four``: Fx, Fz, torque and the load cell (torque / 10 cm), each with its own noise
  (5 % of its RMS; the load cell's noise is independent of the torque sensor's);
* ``no_Fx``: without the Fx channel;
* ``k_known``: the study's channels, strength k known to 0.1 % (prior N(k_true, 0.001^2)):
  what the strength prior costs;
* foot only: ``length_known`` (the foot length fixed at the truth: the grid's nodes all at
  the true length) and ``length_and_k_known``.
Not a tuning of the study: its sensors, noise and prior stay as they are.

Usage: python benchmarks/dddas_identification_ceiling.py [--trials 20] [--leg foot ...]
(writes benchmarks/results/dddas_identification_ceiling.json)
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

import numpy as np

from terradyn.dddas.forecast import FOOT_LEVER_ARM, make_trial, prior_rms, sensor_channels
from terradyn.dddas.terrain import COMPONENTS, LEG_KINDS, MEDIA, Channel, TerrainFilter, TerrainModel, _nb_table

AT = 0.3


def readings(tr, rng, noise=0.05):
    """The trial's channels plus the ones it lacks (torque or load cell), each with its own
    noise (``noise`` x its RMS) and bias (2 % RMS), like make_trial's."""
    F = {c: tr["truth"][:, j] for j, c in enumerate(COMPONENTS)}
    obs, chans = dict(tr["obs"]), {n: (w, sd) for n, w, sd in tr["channels"]}
    extra = {"torque": {"torque": 1.0}, "load_cell": {"torque": 1.0 / FOOT_LEVER_ARM}}
    for name, w in extra.items():
        if name in obs:
            continue
        clean = Channel(name, w, 1.0).of(F)
        rms = float(np.sqrt(np.mean(clean ** 2)))
        sd = max(noise * rms, 1e-9)
        obs[name] = clean + 0.02 * rms * rng.standard_normal() + sd * rng.standard_normal(len(clean))
        chans[name] = (w, sd)
    return obs, chans


def grid_map(model, tr, obs, chans, names, k_std=0.1, k_mean=1.0, bias_prior=None, fix=()):
    ch = [Channel(n, chans[n][0], chans[n][1], bias_prior[n]) for n in names]
    g = TerrainFilter.on_grid(model, ch, k_std=k_std)
    if fix:
        u = model.unit(tr["condition"])[0]
        for name in fix:
            j = model.inputs.index(name)
            g.U[:, j] = u[j]
        _nb_table(model.table, g.mi, g.U, g.Z)
    if k_mean != 1.0:
        g.mk = k_mean
        g.kpost[0] = k_mean
    cut = int(round(AT * len(tr["theta"])))
    for i in range(cut):
        g.update(tr["theta"][i], {n: obs[n][i] for n in names})
    p = g.medium_probabilities()
    return max(p, key=p.get), p[tr["medium"]]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--trials", type=int, default=20)
    ap.add_argument("--leg", action="append", choices=LEG_KINDS)
    a = ap.parse_args()
    legs = a.leg or list(LEG_KINDS)
    load = os.getloadavg()[0]
    out = {"machine": platform.platform(), "cpus": os.cpu_count(), "load_average_before": load,
           "fraction": AT, "trials_per_medium": a.trials, "legs": {}}
    t_all = time.perf_counter()
    for leg in legs:
        t0 = time.perf_counter()
        model = TerrainModel.from_rft(leg, seed=0)
        rms_prior = prior_rms(model, [("Fx", {"Fx": 1.0}), ("Fz", {"Fz": 1.0}), ("torque", {"torque": 1.0}),
                                      ("load_cell", {"torque": 1.0 / FOOT_LEVER_ARM})])
        bias_prior = {n: 0.05 * v for n, v in rms_prior.items()}
        study = [n for n, _ in sensor_channels(leg)]
        variants = {"study": (study, {}), "all_four": (["Fx", "Fz", "torque", "load_cell"], {}),
                    "no_Fx": ([n for n in study if n != "Fx"], {}), "k_known": (study, {"k_known": True})}
        if leg == "foot":
            variants["length_known"] = (study, {"fix": ("length_cm",)})
            variants["length_and_k_known"] = (study, {"fix": ("length_cm",), "k_known": True})
        rng = np.random.default_rng(0)  # trials as make_trial draws them (seed 0 for each leg)
        rng_extra = np.random.default_rng(1)
        res = {v: {"correct": [], "p_true": []} for v in variants}
        for t in range(len(MEDIA) * a.trials):
            tr = make_trial(leg, model, rng, MEDIA[t % len(MEDIA)])
            obs, chans = readings(tr, rng_extra)
            for v, (names, opt) in variants.items():
                kw = {"k_std": 0.001, "k_mean": tr["k"]} if opt.get("k_known") else {}
                kw["fix"] = opt.get("fix", ())
                m, p = grid_map(model, tr, obs, chans, names, bias_prior=bias_prior, **kw)
                res[v]["correct"].append(m == tr["medium"])
                res[v]["p_true"].append(p)
        out["legs"][leg] = {v: {"channels": variants[v][0], "medium_correct": float(np.mean(r["correct"])),
                                "p_true_medium_mean": float(np.mean(r["p_true"]))} for v, r in res.items()}
        print(f"{leg} ({time.perf_counter() - t0:.0f} s): " + "; ".join(
            f"{v} {100 * r['medium_correct']:.0f} %" for v, r in out["legs"][leg].items()), flush=True)
    out["seconds"] = time.perf_counter() - t_all
    out["when"] = time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())
    path = Path(__file__).parent / "results" / "dddas_identification_ceiling.json"
    path.write_text(json.dumps(out, indent=2))
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
