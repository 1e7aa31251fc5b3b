"""DDDAS on the human-sized foot: RFT data for lengths 25-35 cm, a surrogate at 29 cm, and a
SYNTHETIC trial's normal force assimilated sample by sample.

Run: python examples/dddas_foot.py [OUTDIR]
"""
import sys

import numpy as np

import terradyn as td
from terradyn import experiment as ex
from terradyn.dddas import Assimilation, Surrogate
from terradyn.dddas import plots
from terradyn.units import CM

out = sys.argv[1] if len(sys.argv) > 1 else "results/example_dddas_foot"
medium = "poppy LP"
model = td.stress_model(medium, alpha="generic")
motion = td.foot_rotation(3.0, 61)
lengths = [25, 26, 27, 28, 30, 31, 32, 33, 34, 35]  # 29 cm held out
stack = td.stack([td.rft.simulate(td.foot(L * CM), motion, model, medium=medium) for L in lengths],
                 {"length_cm": lengths})
sur = Surrogate(inputs=["length_cm"]).fit(stack)
print("HOSVD ranks", sur.ranks_)

trial = ex.synthetic_trial(12.0, length=27 * CM, medium=medium, seed=1)  # labelled synthetic
offset = float(trial.normal_force[:80].mean())  # the foot has not moved yet
trial["normal_force"] = trial.normal_force - offset
obs = ex.to_force_series(trial)

a = Assimilation(sur, {"length_cm": 29.0}, obs_std={"Fz": 0.3}, prior_floor=1.0, n_particles=5000, rng=0)
prior = a.prediction()
for theta, fz in zip(obs.theta.values, obs.Fz.values):
    if theta <= 3.0:
        a.update(theta, Fz=fz)
post = a.prediction()
truth = td.rft.simulate(td.foot(27 * CM), motion, model, medium=medium)
for name, s in (("prior (29 cm)", prior), ("posterior", post)):
    print(f"{name:14s} Fz at 2.5 deg: {float(s.Fz.interp(theta=2.5)):6.2f} N"
          f"  (trial truth, 27 cm foot: {float(truth.Fz.interp(theta=2.5)):6.2f} N)")
print("wrote", plots.prediction(post, f"{out}/foot_assimilation.png", truth=truth, prior=prior,
                                title="foot: SYNTHETIC trial assimilated"))
