"""Sweeps of simulations: a TOML spec expands to cases with stable ids, which run on a local
process pool or a Dask cluster into a resumable store, collected into one labelled tensor.

    import terradyn.sweep as sw
    spec = sw.load("examples/sweeps/rft_foot_lengths.toml")
    summary = sw.run(spec, "foot.sweep")            # local pool; scheduler="tcp://..." for Dask
    ds = sw.collect("foot.sweep", "foot.nc")         # Fx, Fz, torque (case, theta) + coords

See ``docs/sweep.md`` for the TOML format and the store layout.
"""
from .execute import SCHEDULER_ENV, Summary, run, run_case, simulate_case
from .spec import Case, SweepSpec, build, case_id, expand, from_dict, load, parse, resolve
from .store import Store, collect, status

__all__ = ["SCHEDULER_ENV", "Summary", "run", "run_case", "simulate_case", "Case", "SweepSpec",
           "build", "case_id", "expand", "from_dict", "load", "parse", "resolve", "Store", "collect",
           "status"]
