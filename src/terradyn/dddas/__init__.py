"""DDDAS: an offline surrogate (HOSVD + Gaussian processes) and online assimilation
(particle filter, exact Gaussian posterior) of force measurements (thesis ch. 4).

    import terradyn as td
    sur = td.dddas.Surrogate(inputs=["omega"]).fit(stack)      # stack along 'case'
    pred = sur.predict({"omega": 0.5})                          # force series + Fx_std/Fz_std
    a = td.dddas.Assimilation(sur, {"omega": 0.5}, obs_std=0.2)  # streaming
    a.update(theta_deg, Fz=measured); post = a.prediction()
    tm = td.dddas.TerrainModel.from_rft("flat")                 # unknown terrain (issue 13)
    f = td.dddas.TerrainFilter(tm, [td.dddas.Channel("Fz", noise=0.1)])
    f.update(theta_deg, {"Fz": measured}); f.summary(); f.forecast()
"""
from .crossval import cross_validate
from .filter import GaussianPosterior, ParticleFilter
from .hosvd import HOSVD, hosvd
from .online import Assimilation, assimilate
from .surrogate import Surrogate
from .terrain import Channel, TerrainFilter, TerrainModel

__all__ = ["Surrogate", "HOSVD", "hosvd", "ParticleFilter", "GaussianPosterior", "Assimilation",
           "assimilate", "cross_validate", "TerrainModel", "TerrainFilter", "Channel"]
