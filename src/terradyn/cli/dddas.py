"""``terradyn dddas``: fit, cross-validate, predict and assimilate with the DDDAS surrogate."""
from __future__ import annotations

import json
import sys
from enum import Enum
from pathlib import Path
from typing import List, Optional

import typer

from ..errors import renamed
from . import sub_app

Method = Enum("Method", {"pf": "pf", "exact": "exact"}, type=str)
Resampler = Enum("Resampler", {"systematic": "systematic", "multinomial": "multinomial"}, type=str)
Study = Enum("Study", {"legs": "legs", "foot": "foot", "speed": "speed"}, type=str)


def _err(msg):
    from . import err

    err(msg)


def _conditions(at: List[str]) -> dict:
    from ..errors import InputError

    out = _pairs(at, "at")
    if not out:
        raise InputError("at", "give the condition, e.g. --at omega=0.5")
    return out


def _estimator(inputs, energy, step_energy, center, restarts, seed):
    from ..dddas import Surrogate

    est = Surrogate(inputs=inputs or None, energy=energy, step_energy=step_energy, center=center,
                    n_restarts=restarts, random_state=seed)
    est._check_params()  # bad hyperparameters fail before the data are read
    return est


def register(app: typer.Typer) -> None:
    dd = sub_app(help="DDDAS: surrogate (HOSVD + Gaussian processes) and online assimilation.",
                     no_args_is_help=True)
    app.add_typer(dd, name="dddas")

    @dd.command()
    def fit(
        data: Path = typer.Argument(..., help="Stacked force series along 'case' (.nc/.zarr) with condition coordinates."),
        out: Path = typer.Option(..., "--out", "-o", help="Model file to write (.nc)."),
        inputs: List[str] = typer.Option([], "--input", "-i", help="Condition coordinate(s) to regress on [default: all numeric ones along case]."),
        energy: float = typer.Option(0.95, help="Cumulative explained variance kept in the condition mode (sets D)."),
        step_energy: float = typer.Option(0.9999, help="The same for the step and component modes."),
        center: bool = typer.Option(True, help="Subtract the mean trajectory before the HOSVD (--no-center: thesis form)."),
        restarts: int = typer.Option(2, help="GP optimizer restarts."),
        seed: int = typer.Option(0, help="Seed for the optimizer restarts."),
        plot: Optional[Path] = typer.Option(None, help="Explained-variance figure (.png)."),
    ):
        """Fit the surrogate to a stack of force series and save it (NetCDF, no pickle)."""
        from .. import io

        io.check_input(data, "data")
        io.check_output(out, "out", (".nc",))
        io.check_plot(plot)
        sur = _estimator(inputs, energy, step_energy, center, restarts, seed).fit(io.read(data, "data"))
        sur.save(out)
        if plot:
            from ..dddas import plots

            plots.explained_variance(sur, plot)
        _err(f"fitted: inputs {sur.input_names_}, HOSVD ranks {sur.ranks_}; wrote {out}")

    @dd.command()
    def cv(
        data: Path = typer.Argument(..., help="Stacked force series along 'case' (.nc/.zarr)."),
        out: Optional[str] = typer.Option(None, "--out", "-o", help="Table (.csv) or full result (.nc) [default: CSV on stdout]."),
        inputs: List[str] = typer.Option([], "--input", "-i", help="Condition coordinate(s)."),
        energy: float = typer.Option(0.95, help="Cumulative explained variance kept in the condition mode (sets D)."),
        step_energy: float = typer.Option(0.9999, help="The same for the step and component modes."),
        center: bool = typer.Option(True, help="Subtract the mean trajectory before the HOSVD."),
        restarts: int = typer.Option(2, help="GP optimizer restarts."),
        seed: int = typer.Option(0, help="Seed for the optimizer restarts."),
        baseline: Optional[Path] = typer.Option(None, help="Another stack on the same cases (e.g. RFT) to compare errors with."),
        plot: Optional[Path] = typer.Option(None, help="Figure of the errors (.png)."),
    ):
        """Leave-one-condition-out cross-validation: mean square error (N^2) per case and component."""
        from .. import io
        from ..dddas.crossval import cross_validate, mse_table

        io.check_input(data, "data")
        io.check_input(baseline, "baseline")
        io.check_output(out, "out", (".csv", ".nc"))
        io.check_plot(plot)
        ds = io.read(data, "data")
        res = cross_validate(ds, _estimator(inputs, energy, step_energy, center, restarts, seed),
                             io.read(baseline, "baseline") if baseline else None,
                             progress=lambda i, n: _err(f"fold {i}/{n}"))
        if out and out.lower().endswith(".nc"):
            io.write_netcdf(res, out)
        else:
            text = mse_table(res).to_csv(index=False, float_format="%.6g")
            io.atomic_write_text(out, text) if out and out != "-" else sys.stdout.write(text)
        if plot:
            from ..dddas import plots

            plots.cv_errors(res, plot)
        _err(f"cross-validation of {res.sizes['case']} cases in {res.attrs['seconds']:.2f} s")

    @dd.command()
    def predict(
        model: Path = typer.Argument(..., help="Model file from 'dddas fit'."),
        at: List[str] = typer.Option([], "--at", help="Condition NAME=VALUE (repeat for several inputs)."),
        out: Optional[str] = typer.Option(None, "--out", "-o", help="Output .nc/.zarr/.csv [default: CSV on stdout]."),
        plot: Optional[Path] = typer.Option(None, help="Figure with +-2 std bands (.png)."),
    ):
        """Predicted force series (Fx, Fz in N) with standard deviations at a condition."""
        from .. import io
        from ..dddas import Surrogate

        io.check_input(model, "model")
        io.check_output(out, "out")
        io.check_plot(plot)
        cond = _conditions(at)
        with renamed(**{"model file": "model"}):
            sur = Surrogate.load(model)
        pred = sur.predict(cond)
        io.emit(pred, out)
        if plot:
            from ..dddas import plots

            plots.prediction(pred, plot, title=f"surrogate at {_conditions(at)}")

    @dd.command()
    def assimilate(
        model: Path = typer.Argument(..., help="Model file from 'dddas fit'."),
        obs: str = typer.Option(..., "--obs", help="Observations: CSV (theta_deg or time_s, Fx_N and/or Fz_N; empty = missing), .nc, or '-' to stream CSV lines on standard input."),
        at: List[str] = typer.Option([], "--at", help="Condition NAME=VALUE."),
        obs_std_n: float = typer.Option(0.1, "--obs-std-N", help="Sensor noise standard deviation, N."),
        method: Method = typer.Option(Method.pf, help="pf: particle filter; exact: Gaussian posterior."),
        particles: int = typer.Option(5000, help="Number of particles."),
        resample: Resampler = typer.Option(Resampler.systematic, help="Resampling scheme."),
        jitter: float = typer.Option(0.1, help="Liu-West jitter bandwidth in [0, 1)."),
        prior_floor: float = typer.Option(0.0, help="Prior std floor as a fraction of the training coefficients' spread."),
        jitter_floor: float = typer.Option(0.0, help="Particle-filter process noise: jitter std floor as a fraction of the prior std."),
        seed: int = typer.Option(0, help="Random seed."),
        out: Optional[str] = typer.Option(None, "--out", "-o", help="Posterior series .nc/.zarr/.csv [default: CSV on stdout]."),
        plot: Optional[Path] = typer.Option(None, help="Figure of prior, observations and posterior (.png)."),
    ):
        """Correct the surrogate's prediction with noisy force samples (file or stream)."""
        from .. import io
        from ..dddas import Surrogate
        from ..dddas.online import Assimilation, assimilate as assimilate_file, read_observations, stream_csv
        from ..errors import check_memory, in_range, integer, non_negative, positive

        io.check_input(model, "model")
        if obs != "-":
            io.check_input(obs, "obs")
        io.check_output(out, "out")
        io.check_plot(plot)
        positive("obs-std-N", obs_std_n, "N")
        non_negative("prior-floor", prior_floor)
        non_negative("jitter-floor", jitter_floor)
        if method.value == "pf":
            integer("particles", particles, 1)
            in_range("jitter", jitter, 0.0, 1.0)
            if jitter >= 1.0:
                from ..errors import InputError

                raise InputError("jitter", f"must be in [0, 1), got {jitter!r}")
            check_memory("particles", particles * 8.0 * 64 * 4, f"{particles:,} particles")
        else:
            from ..models import ignored

            for name, v, d in (("particles", particles, 5000), ("jitter", jitter, 0.1),
                               ("jitter-floor", jitter_floor, 0.0), ("resample", resample, Resampler.systematic)):
                if v != d:
                    ignored(name, "has no effect with --method exact")
        cond = _conditions(at)
        with renamed(**{"model file": "model"}):
            sur = Surrogate.load(model)
        sur.warn_extrapolation(cond)
        opts = dict(n_particles=particles, resample=resample.value, jitter=jitter, jitter_floor=jitter_floor,
                    rng=seed) if method.value == "pf" else {}
        observations = None
        if obs == "-":
            a = Assimilation(sur, cond, obs_std_n, method.value, prior_floor=prior_floor, **opts)
            prior = a.prediction()
            n = stream_csv(a, sys.stdin, every=100, report=lambda i, e: _err(f"{i} samples, ESS {e:.0f}"))
            post = a.prediction()
        else:
            observations = read_observations(obs)
            prior = Assimilation(sur, cond, obs_std_n, method.value, prior_floor=prior_floor,
                                 **opts).prediction() if plot else None
            post = assimilate_file(sur, cond, observations, obs_std_n, method.value,
                                   prior_floor=prior_floor, **opts)
            n = post.attrs["samples_assimilated"]
        io.emit(post, out)
        if plot:
            from ..dddas import plots

            plots.prediction(post, plot, observations=observations, prior=prior,
                             title=f"{method.value} posterior after {n} samples")
        _err(f"assimilated {n} samples ({method.value})")

    _register_terrain(dd)

    def _legs_summary(s):
        """A short human-readable summary on stderr: the data each leg used and its errors."""
        from rich.markup import escape

        if s["data"].get("fallback_to_rft"):
            _err(escape(f"WARNING: {s['data']['message']}"))
        for leg, r in s["legs"].items():
            cv, pf = r["cv_mse_mean_N2"], r["assimilation"]["mse_pf_N2"]
            _err(escape(f"{leg}: {r['data_label']}; {r['n_conditions']} conditions of {', '.join(r['inputs'])}; "
                 f"ranks {r['ranks']}; LOO CV mean MSE Fx/Fz {cv['Fx']:.3f}/{cv['Fz']:.3f} N^2 "
                 f"(thesis {r['reported_cv_mse_N2']:g}); PF posterior MSE Fx/Fz {pf['Fx']:.3f}/{pf['Fz']:.3f} N^2"))

    def _speed_summary(s):
        """Per leg, each filter's mean MSE over the prior's (assimilation score) on stderr."""
        for leg, r in s["legs"].items():
            q = r["mean_over_prior"]["assimilation"]
            _err(f"{leg}: {r['data_label']}; {r['held_out_cases']} held-out cases x {len(s['seeds'])} seeds; "
                 "mean posterior MSE / prior MSE, Fx/Fz: " + "; ".join(
                     f"{m} {q[m]['Fx']:.3f}/{q[m]['Fz']:.3f}" for m in ("pf", "pf_move", "exact")))

    @dd.command()
    def study(
        which: Study = typer.Argument(..., help="legs: three legs across ten conditions; foot: human-sized foot; "
                                      "speed: the thesis's speed study over every held-out case of the legs' data, "
                                      "noise seeds SEED and SEED + 1 (speed_study.json, speed_study.png)."),
        out: Path = typer.Option(Path("results/dddas"), "--out", "-o", help="Output folder."),
        data: List[str] = typer.Option([], "--data", help="legs: FILE stacking all legs with a 'shape' coordinate, LEG=FILE (a stack for one leg), or a keyword: 'sph' (the shipped SPH training set datasets/sph_legs_speeds.nc), 'rft' (RFT-generated stand-in, hip height varies); also LEG=sph|rft. Default: the shipped SPH set, or RFT-generated data with a warning where it is not found (set TERRADYN_DATASETS=DIR)."),
        trial: Optional[Path] = typer.Option(None, help="foot: trial CSV [default: a synthetic trial]."),
        leg: List[str] = typer.Option([], "--leg", help="legs, speed: the legs to study (repeat; flat, c, reverse-c) [default: all three]."),
        particles: int = typer.Option(5000, help="Number of particles."),
        seed: int = typer.Option(0, help="Random seed."),
    ):
        """Run a DDDAS study: datasets, figures and summary.json in --out."""
        from .. import io
        from ..dddas import studies
        from ..errors import InputError, check_memory, choice, integer
        from ..models import ignored

        io.check_writable(out, "out", directory=True)
        integer("particles", particles, 1)
        check_memory("particles", particles * 8.0 * 64 * 4, f"{particles:,} particles")
        if which.value in ("legs", "speed") and trial is not None:
            ignored("trial", f"has no effect with the {which.value} study")
        if which.value == "foot" and data:
            ignored("data", "has no effect with the foot study")
        if which.value == "foot" and leg:
            ignored("leg", "has no effect with the foot study")
        legs = tuple(dict.fromkeys(choice("leg", x, list(studies.LEGS)) for x in leg)) or studies.LEGS
        if leg and len(legs) != len(leg):
            raise InputError("leg", f"each leg once, got {list(leg)}")
        io.check_input(trial, "trial")
        if trial is not None and which.value == "foot":
            from ..experiment import read_trial

            read_trial(trial)  # a bad trial: an error before the study's work
        if which.value in ("legs", "speed"):
            d = {}
            for item in data:
                k, v = item.split("=", 1) if "=" in item else ("all", item)
                if k != "all" and k not in studies.LEGS:
                    raise InputError("data", f"{item!r}: unknown leg {k!r}; allowed: {', '.join(studies.LEGS)}")
                if v not in ("sph", "rft"):
                    if Path(v).suffix.lower() not in (".nc", ".zarr", ".csv"):
                        raise InputError("data", f"{item!r}: not 'sph', 'rft' or a .nc/.zarr/.csv file")
                    io.check_input(v, "data")
                if k != "all" and k not in legs:
                    ignored("data", f"{item!r}: the {k} leg is not among --leg {', '.join(legs)}")
                d[k] = v
            with renamed(file="data"):
                if which.value == "legs":
                    s = studies.legs_study(out, d, legs=legs, particles=particles, seed=seed, progress=_err)
                else:
                    s = studies.speed_study(out, d, legs=legs, seeds=(seed, seed + 1), particles=particles,
                                            progress=_err)
            if which.value == "legs":
                _legs_summary(s)
            else:
                _speed_summary(s)
        else:
            s = studies.foot_study(out, trial=trial, particles=particles, seed=seed, progress=_err)
        sys.stdout.write(json.dumps(s, indent=2, default=float) + "\n")


# ---------------------------------------------------------------------------- terrain (issue 13)
Leg = Enum("Leg", {k: k for k in ("flat", "c", "reverse-c", "foot")}, type=str)


def _pairs(items: List[str], field: str) -> dict:
    """NAME=VALUE options (each name once) -> dict of floats."""
    from ..errors import InputError

    out = {}
    for a in items:
        if "=" not in a:
            raise InputError(field, f"expected NAME=VALUE, got {a!r}")
        k, v = (x.strip() for x in a.split("=", 1))
        if not k:
            raise InputError(field, f"expected NAME=VALUE, got {a!r} (no name)")
        if k in out:
            raise InputError(field, f"{k} given twice; give each once")
        try:
            out[k] = float(v)
        except ValueError:
            raise InputError(field, f"{k}: not a number: {v!r}") from None
    return out


def _register_terrain(dd: typer.Typer) -> None:
    @dd.command()
    def forecast(
        out: Path = typer.Option(Path("results/dddas_forecast"), "--out", "-o", help="Output folder (forecast.nc, summary.json, figures)."),
        leg: List[Leg] = typer.Option([], "--leg", help="Leg(s) to run (default: all four: flat, c, reverse-c, foot)."),
        trials: int = typer.Option(20, help="Trials per medium (five media) and leg."),
        noise: float = typer.Option(0.05, help="Sensor noise std as a fraction of each channel's RMS."),
        bias: float = typer.Option(0.02, help="Sensor bias std as a fraction of each channel's RMS."),
        k_std: float = typer.Option(0.1, help="Std of the medium's strength factor k (prior and trials)."),
        particles: int = typer.Option(5000, help="Particles of both particle filters."),
        seed: int = typer.Option(0, help="Random seed."),
    ):
        """Forecast skill: assimilate 10 %, 20 %, ... 90 % of a stroke, forecast the rest, score against
        the noise-free truth (prior, terrain filter, present filter, exact posterior, oracle, naive)."""
        from ..dddas.forecast import forecast_study, summarise
        from ..errors import InputError, integer
        from ..io import check_writable

        integer("trials", trials, 1)
        if integer("particles", particles, 2) > 1_000_000:
            raise InputError("particles", f"must be in [2, 1000000], got {particles}")
        check_writable(out, "out", directory=True)
        ds = forecast_study(out, [l.value for l in leg] or [l.value for l in Leg], trials,
                            noise, bias, k_std, particles, seed, progress=_err)
        s = summarise(ds)
        for name, r in s["legs"].items():
            tp, to = r["terrain_over"]["prior"], r["terrain_over"]["oracle"]
            go = r["grid_over_oracle_by_fraction"].get(s["fraction"], {})
            _err(f"{name} at 30 %: medium correct {100 * r['medium_correct']:.1f} % (exact Bayes "
                 f"{100 * r['medium_correct_exact_bayes_grid']:.1f} %); forecast MSE terrain/prior "
                 + ", ".join(f"{c} {v:.3g}" for c, v in tp.items()) + "; terrain/oracle "
                 + ", ".join(f"{c} {v:.1f}" for c, v in to.items()) + "; exact Bayes/oracle "
                 + ", ".join(f"{c} {v:.1f}" for c, v in go.items()))
        _err(f"wrote {out}/forecast.nc, summary.json, forecast_mse.png, identification.png")
        sys.stdout.write(json.dumps(s, indent=2) + "\n")

    @dd.command()
    def identify(
        obs: str = typer.Option(..., "--obs", help="Sensor CSV: theta_deg and any of Fx_N, Fz_N, torque_Nm, load_cell_N (empty = missing), or '-' for lines on standard input."),
        leg: Leg = typer.Option(Leg.flat, "--leg", help="Leg (the terrain model is trained on RFT sweeps of it)."),
        noise: List[str] = typer.Option([], "--noise", help="CHANNEL=STD sensor noise in the channel's units (N; N m for torque); default 0.1 each."),
        bias_std: List[str] = typer.Option([], "--bias-std", help="CHANNEL=STD prior std of the channel's bias; default 0."),
        lever_arm_cm: float = typer.Option(10.0, "--lever-arm-cm", help="Lever arm of the load cell (it reads torque / arm), cm."),
        k_std: float = typer.Option(0.1, help="Prior std of the strength factor k (zeta = k x zeta of the medium)."),
        particles: int = typer.Option(5000, help="Number of particles."),
        seed: int = typer.Option(0, help="Random seed."),
        stream_out: bool = typer.Option(False, "--stream", help="One JSON line per sample on stdout (terrain posterior and forecast of the rest of the stroke)."),
        out: Optional[str] = typer.Option(None, "--out", "-o", help="Posterior trace .nc or .csv (default: CSV on stdout)."),
        plot: Optional[Path] = typer.Option(None, help="Figure of the posterior over the stroke (.png)."),
    ):
        """Identify the terrain (which of Li 2013's five media, zeta with a 95 % credible interval, hip
        height / sinkage, foot length) from force samples as the stroke goes on."""
        from .. import io
        from ..dddas import plots
        from ..dddas.terrain import TerrainFilter, TerrainModel, channels_for, parse_header, read_samples, stream, trace
        from ..errors import InputError, integer, positive
        from ..units import CM

        noise_d, bias_d = _pairs(noise, "noise"), _pairs(bias_std, "bias-std")
        arm = positive("lever-arm-cm", lever_arm_cm, "cm") * CM
        if integer("particles", particles, 2) > 1_000_000:
            raise InputError("particles", f"must be in [2, 1000000], got {particles}")
        if out is not None:
            io.check_output(out, "out", (".nc", ".csv"))
        io.check_plot(plot)
        if obs == "-":
            lines = iter(sys.stdin)
        else:
            p = Path(obs)
            if not p.is_file():
                raise InputError("obs", f"file not found: {p}")
            lines = iter(p.read_text().splitlines())
        header = next((ln for ln in lines if ln.strip() and not ln.lstrip().startswith("#")), None)
        if header is None:
            raise InputError("observations", "no header line")
        _, cols = parse_header(header)
        channels = channels_for(list(cols), noise_d, bias_d, arm)
        samples = read_samples(_chain(header, lines))
        model = TerrainModel.from_rft(leg.value, seed=seed)
        filt = TerrainFilter(model, channels, k_std=k_std, n_particles=particles, seed=seed)
        if stream_out:
            n = 0
            for r in stream(filt, samples):
                sys.stdout.write(json.dumps(r) + "\n")
                sys.stdout.flush()
                n += 1
            if n == 0:
                raise InputError("observations", "no samples on the stream (only a header?)")
            _err(f"streamed {n} samples; most probable medium {filt.summary()['medium']}")
            return
        ds = trace(filt, samples)
        if out and out.endswith(".nc"):
            tmp = Path(out).with_name(f".{Path(out).name}.tmp")
            ds.to_netcdf(tmp, engine="h5netcdf")
            tmp.replace(out)
        else:
            text = ds.to_dataframe().reset_index().pivot_table(index="theta", columns="medium", values="p_medium")
            table = ds.drop_vars("p_medium").drop_dims("medium").to_dataframe().join(
                text.add_prefix("p_")).reset_index().rename(columns={"theta": "theta_deg"})
            csv = table.to_csv(index=False, float_format="%.6g")
            io.atomic_write_text(out, csv) if out else sys.stdout.write(csv)
        if plot:
            plots.terrain_trace(ds, plot, f"{leg.value}: terrain posterior during the stroke")
        s = filt.summary()
        z = s["zeta"]
        _err(f"{s['samples']} samples: most probable medium {s['medium']} "
             f"(P = {s['medium_probabilities'][s['medium']]:.3f}); zeta {z['mean']:.3f} "
             f"[{z['lo']:.3f}, {z['hi']:.3f}] (95 %)")


def _chain(header, lines):
    yield header
    yield from lines
