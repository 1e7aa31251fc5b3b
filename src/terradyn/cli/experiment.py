"""``terradyn experiment``: read, filter, compare and calibrate trials; make synthetic ones."""
from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import List, Optional

import typer

from ..errors import non_negative, positive, renamed
from . import options as O, sub_app


def _pairs(items: List[str], field: str) -> dict:
    from ..errors import InputError

    out = {}
    for it in items:
        if "=" not in it:
            raise InputError(field, f"expected VAR=VALUE, got {it!r}")
        k, v = it.split("=", 1)
        out[k.strip()] = v.strip()
    return out


def _read(path: Path, column: List[str], unit: List[str]):
    from ..experiment import read_trial

    with renamed(columns="column", units="unit"):
        return read_trial(path, _pairs(column, "column"), _pairs(unit, "unit"))


_COL = "Column name VAR=NAME (VAR: time, angle_cmd, angle, speed_cmd, speed, torque, normal_force)."
_UNIT = "Unit VAR=UNIT (time ms|s|us; angles deg|rad; speeds deg/s|rad/s; torque 'N m'|'N mm'|'N cm'; force N|kN|lbf|kgf)."


def _outputs(out, plot=None, formats=(".csv",)):
    from .. import io

    io.check_output(out, "out", formats)
    io.check_plot(plot)


def register(app: typer.Typer) -> None:
    ex = sub_app(help="Experimental trials: filter, compare with RFT, calibrate, synthesize.")
    app.add_typer(ex, name="experiment")

    @ex.command("filter")
    def filter_(
        trial: Path = typer.Argument(..., help="Trial CSV (defaults: time_ms, angle_cmd_deg, angle_deg, speed_cmd_deg_s, speed_deg_s, torque_Nm, normal_force_N)."),
        cutoff_hz: float = typer.Option(10.0, "--cutoff-hz", help="Low-pass cut-off, Hz (below the Nyquist frequency)."),
        order: int = typer.Option(4, help="Butterworth order, 1-12 (applied forward and backward)."),
        column: List[str] = typer.Option([], "--column", help=_COL),
        unit: List[str] = typer.Option([], "--unit", help=_UNIT),
        out: Optional[Path] = O.out("Filtered trial CSV", "stdout"),
    ):
        """Zero-phase Butterworth low-pass of torque and normal force."""
        from ..experiment import lowpass, trial_csv_text, write_trial

        _outputs(out)
        positive("cutoff-hz", cutoff_hz, "Hz")
        with renamed(variables="column"):
            f = lowpass(_read(trial, column, unit), cutoff_hz, order)
        if out is None or str(out) == "-":
            sys.stdout.write(trial_csv_text(f))
        else:
            write_trial(f, out)

    @ex.command()
    def compare(
        trial: Path = typer.Argument(..., help="Trial CSV."),
        length_cm: float = typer.Option(27.0, "--length-cm", help="Nominal foot length, cm."),
        zeta: Optional[float] = typer.Option(None, help="Scaling factor of the generic fit (default: the medium's)."),
        medium: str = typer.Option("poppy LP", help="Medium (for the default zeta)."),
        offset_n: float = typer.Option(0.0, "--offset-N", help="Offset added to the model normal force, N."),
        cutoff_hz: float = typer.Option(10.0, "--cutoff-hz", help="Low-pass cut-off, Hz."),
        order: int = typer.Option(4, help="Butterworth order."),
        column: List[str] = typer.Option([], "--column", help=_COL),
        unit: List[str] = typer.Option([], "--unit", help=_UNIT),
        out: Optional[Path] = O.out("Comparison dataset (.nc)", "none"),
        plot: Optional[Path] = typer.Option(None, help="Figure: raw, filtered and model (.png)."),
    ):
        """Compare a trial with the RFT foot model at the trial's actual angles."""
        from .. import io
        from ..experiment import compare as cmp_
        from ..units import CM

        _outputs(out, plot, (".nc",))
        positive("length-cm", length_cm, "cm")
        positive("cutoff-hz", cutoff_hz, "Hz")
        if zeta is not None:
            positive("zeta", zeta)
        c = cmp_(_read(trial, column, unit), length_cm * CM, zeta, medium, offset_n, cutoff_hz, order)
        if out:
            io.write_netcdf(c, out)
        if plot:
            from ..dddas import plots

            plots.trial_comparison(c, plot, f"{trial.name} vs RFT foot {length_cm:g} cm")
        sys.stdout.write(json.dumps({k: v for k, v in c.attrs.items()}, indent=2, allow_nan=False) + "\n")

    @ex.command()
    def calibrate(
        trial: Path = typer.Argument(..., help="Trial CSV."),
        fit: List[str] = typer.Option(["length", "offset"], "--fit", help="Parameters to fit: length, zeta, offset."),
        use: List[str] = typer.Option(["normal_force"], "--use", help="Channels: normal_force, torque."),
        length_cm: float = typer.Option(25.0, "--length-cm", help="Initial / fixed nominal length, cm."),
        zeta: Optional[float] = typer.Option(None, help="Initial / fixed zeta (default: the medium's)."),
        offset_n: float = typer.Option(0.0, "--offset-N", help="Initial / fixed offset, N."),
        medium: str = typer.Option("poppy LP", help="Medium (for the default zeta)."),
        column: List[str] = typer.Option([], "--column", help=_COL),
        unit: List[str] = typer.Option([], "--unit", help=_UNIT),
    ):
        """Least-squares calibration of the RFT foot model; values with standard errors (JSON)."""
        from ..experiment import calibrate as cal
        from ..units import CM

        positive("length-cm", length_cm, "cm")
        if zeta is not None:
            positive("zeta", zeta)
        init = {"length": length_cm * CM, "offset": offset_n}
        if zeta is not None:
            init["zeta"] = zeta
        with renamed(params="fit", use="use", initial="length-cm"):
            r = cal(_read(trial, column, unit), fit, use, init, medium)
        r["values"]["length_cm"] = r["values"]["length"] / CM
        if "length" in r["std"]:
            r["std"]["length_cm"] = r["std"]["length"] / CM
        sys.stdout.write(json.dumps(r, indent=2) + "\n")

    @ex.command()
    def synth(
        out: Path = typer.Option(..., "--out", "-o", help="Trial CSV to write (labelled SYNTHETIC)."),
        commanded_deg: float = typer.Option(3.0, "--commanded-deg", help="Commanded angle, deg."),
        reached_deg: Optional[float] = typer.Option(None, "--reached-deg", help="Angle reached (default: thesis 3/7/12 -> 0.84/1.7/2.6 deg)."),
        length_cm: float = typer.Option(27.0, "--length-cm", help="Nominal foot length of the model, cm."),
        medium: str = typer.Option("poppy LP", help="Medium."),
        offset_n: float = typer.Option(-0.5, "--offset-N", help="Sensor bias, N."),
        noise_n: float = typer.Option(0.3, "--noise-N", help="Normal-force noise std, N."),
        lag_s: float = typer.Option(0.02, "--lag-s", help="Force lag behind the angle, s."),
        rate_hz: float = typer.Option(200.0, "--rate-hz", help="Sampling rate, Hz."),
        duration_s: float = typer.Option(6.0, "--duration-s", help="Duration, s."),
        seed: int = typer.Option(0, help="Random seed."),
    ):
        """Write a SYNTHETIC trial (RFT foot + noise, bias, lag) - no real trials are public."""
        from ..experiment import synthetic_trial, write_trial
        from ..units import CM

        _outputs(out)
        positive("length-cm", length_cm, "cm")
        non_negative("noise-N", noise_n, "N")
        non_negative("lag-s", lag_s, "s")
        with renamed(commanded="commanded-deg", reached="reached-deg", rate="rate-hz",
                     duration="duration-s", lag="lag-s", noise="noise-N", seed="seed"):
            t = synthetic_trial(commanded_deg, reached_deg, length_cm * CM, None, medium, offset_n, lag_s,
                                noise_n, rate=rate_hz, duration=duration_s, seed=seed)
        write_trial(t, out)
        from . import err

        err(f"wrote SYNTHETIC trial {out} ({t.sizes['time']} samples)")
