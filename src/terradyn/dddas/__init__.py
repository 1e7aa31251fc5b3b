"""DDDAS: an offline surrogate (HOSVD + Gaussian processes) and online assimilation
(particle filter, exact Gaussian posterior) of force measurements (thesis ch. 4).

    import terradyn as td
    sur = td.dddas.Surrogate(inputs=["omega"]).fit(stack)      # stack along 'case'
    pred = sur.predict({"omega": 0.5})                          # force series + Fx_std/Fz_std
    a = td.dddas.Assimilation(sur, {"omega": 0.5}, obs_std=0.2)  # streaming
    a.update(theta_deg, Fz=measured); post = a.prediction()
"""
from .crossval import cross_validate
from .filter import GaussianPosterior, ParticleFilter
from .hosvd import HOSVD, hosvd
from .online import Assimilation, assimilate
from .surrogate import Surrogate

__all__ = ["Surrogate", "HOSVD", "hosvd", "ParticleFilter", "GaussianPosterior", "Assimilation",
           "assimilate", "cross_validate"]
