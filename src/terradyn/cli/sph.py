"""``terradyn sph``: the SPH granular-bed model and its validation scenes."""
from __future__ import annotations

import json
import sys
from contextlib import contextmanager
from enum import Enum
from pathlib import Path
from typing import Optional

import typer

from . import options as O, sub_app

from ..errors import InputError, integer, positive

Backend = Enum("Backend", {b: b for b in ("cpu", "gpu", "auto")}, type=str)

sph_app = sub_app(help="SPH (Drucker-Prager granular bed) forces and validation scenes.",
                      no_args_is_help=True)

_QUICK = typer.Option(False, "--quick", help="Coarse resolution (4 mm particles) for tests and previews.")
from ..models.sph import DX_MM_MAX  # noqa: E402  (largest spacing accepted, mm)
_DX = typer.Option(None, "--dx-mm", help=f"Particle spacing, mm, in (0, {DX_MM_MAX:g}] "
                                         "(default: 2.5; --quick 4).")
_BACKEND = typer.Option(Backend.cpu, "--backend",
                        help="Kernels: cpu (multi-threaded), gpu (NVIDIA, needs the 'gpu' extra) "
                             "or auto (the GPU when one is usable).")
_MEDIUM = typer.Option("3 mm glass CP", help="Medium (Li 2013 Table S1 name), e.g. '3 mm glass CP', 'poppy LP'; with --density-kg-m3, the name of your own medium.")
_DENSITY = typer.Option(None, "--density-kg-m3", help="Your own medium: bulk density, kg/m^3 (needs --friction-deg; calibrate it with 'terradyn sph calibrate').")
_FRICTION = typer.Option(None, "--friction-deg", help="Friction angle, deg (default: the medium's plate-test calibration shipped with terradyn where there is one, else its angle of repose, Li 2013 Table S1; docs/sph.md).")
_DILATANCY = typer.Option("none", "--dilatancy", help="Flow rule: none (psi = 0) or bolton (a CP medium dilates until its LP packing: psi = (phi_CP - phi_LP) / 0.8, Bolton 1986; poppy CP, 0.3 mm glass CP).")
_DP_MATCH = typer.Option("plane-strain", "--dp-match", help="Drucker-Prager cone matched to the friction angle: plane-strain (alpha = sin(phi)/3, mobilises phi in plane strain) or bui2008 (the former cone, mobilises less; a named medium then takes its repose angle unless --friction-deg is given). docs/sph.md.")
_RHEOLOGY = typer.Option("constant", "--rheology", help="Friction law: constant (rate-independent, the default) or mu-i (Jop et al. 2006's mu(I) of glass beads on the medium's calibrated friction angle; a Li 2013 medium only; docs/sph.md).")
_CHANNEL = typer.Option(None, "--channel-width-cm", help="Side walls of a quasi-2D channel this far apart, cm, with Coulomb friction pressed by the out-of-plane stress (default: none, plane strain; Lube et al. 2005's channel: 10).")
_WALL_FRICTION = typer.Option(None, "--wall-friction-deg", help="Grain-wall friction angle of the side walls, deg, in [0, 60] (default: the medium's friction angle; needs --channel-width-cm).")
_LEG_FRICTION = typer.Option(None, "--leg-friction-deg", help="Grain-leg friction angle, deg, in [0, 60]: Coulomb slip of the grains on the leg's surface (default: none, a rough no-slip leg; docs/sph.md 'Grain-leg friction').")
_BED_PAD = typer.Option(None, "--bed-pad-cm", show_default="6; --quick 3", help="Granular bed beyond the leg's path below the surface, cm, in [1, 50]. The forces depend on it: from 6 to 3 cm the thrust peaks rise 7-51 %, from 6 to 9 cm they change by -16 to +4 % (docs/sph.md 'Bed size').")
_CAL_BED = typer.Option("standard", "--calibration-bed", help="Plate bed of a Li 2013 medium's shipped friction calibration: standard (9.5 cm beside the plate, which holds it up by 1-13 %: the validated default) or large (a bed where the plate's slope has settled: 0.3-2.7 deg steeper; docs/sph.md 'Bed size').")
_BOUNDARY = typer.Option("resolved", "--boundary", help="Leg boundary: resolved (sides kept apart, contact at dx/4) or guard (the model before issue 17).")


def _material(medium: str, density_kg_m3: float | None, friction_deg: float | None,
              dilatancy: str = "none", dp_match: str = "plane-strain", rheology: str = "constant",
              dx: float | None = None, calibration_bed: str = "standard"):
    """The SPH material of the options (:func:`terradyn.models.sph.material`); ``dx`` (m):
    the particle spacing it runs at (a medium's calibration there where one is shipped)."""
    from .. import models
    from ..models.sph import material

    return material(medium, models.get("sph").check_options(
        {"density_kg_m3": density_kg_m3, "friction_deg": friction_deg, "dilatancy": dilatancy,
         "dp_match": dp_match, "rheology": rheology, "dx_mm": None if dx is None else dx * 1e3,
         "calibration_bed": calibration_bed}))


@contextmanager
def _progress(label: str):
    """A rich progress bar on stderr; yields a callback(done_s, total_s). The bar appears at
    the first report, so an error found before the work starts stays a one-line message."""
    from rich.console import Console
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

    prog = Progress(TextColumn("{task.description}"), BarColumn(),
                    TextColumn("{task.percentage:>5.1f}%"), TimeElapsedColumn(),
                    TimeRemainingColumn(), console=Console(stderr=True), transient=False)
    task = []

    def cb(done, total):
        if not task:
            prog.start()
            task.append(prog.add_task(label, total=1.0))
        prog.update(task[0], completed=done, total=total)

    try:
        yield cb
    finally:
        if task:
            prog.stop()


def _dx(dx_mm: float | None) -> float | None:
    """--dx-mm in m (None: the command's default); 0, negative, NaN or too coarse: an error."""
    if dx_mm is None:
        return None
    if not 0.0 < dx_mm <= DX_MM_MAX:  # NaN fails too
        raise InputError("dx-mm", f"must be in (0, {DX_MM_MAX:g}] mm, got {dx_mm!r}")
    return dx_mm * 1e-3


def _config(quick: bool, dx_mm: float | None, cfl: float, lowpass_hz: float | None,
            backend: str = "cpu", boundary: str = "resolved"):
    from ..sph.api import default_config
    from ..sph.solver import resolve_backend

    cfg = default_config(quick, dx=_dx(dx_mm), cfl=cfl, lowpass_hz=lowpass_hz, backend=backend,
                         boundary=boundary)
    resolve_backend(cfg.backend)  # --backend gpu without a GPU: fail before any work
    return cfg


def _resumed(info: dict | None) -> None:
    """Say that a run resumed from its checkpoint, and where (stderr)."""
    if info:
        from . import err

        err(f"resumed from checkpoint {info['checkpoint']} at step {info['step']} "
            f"(t = {info['time_s']:.6g} s of {info['total_s']:.6g} s)")


def _unstable(e) -> None:
    from . import err

    from rich.markup import escape

    err(f"[bold red]error:[/] {escape(str(e))}")
    raise typer.Exit(3)


@sph_app.command("run")
def run_cmd(
    leg: O.Leg = O.leg(),
    leg_file: Optional[Path] = O.LEG_FILE,
    curvature: Optional[float] = O.CURVATURE,
    length_cm: Optional[float] = O.LENGTH_CM,
    width_cm: Optional[float] = O.WIDTH_CM,
    thickness_cm: float = typer.Option(0.64, help="Leg thickness, cm."),
    hip_height_cm: Optional[float] = O.HIP_HEIGHT_CM,
    omega: float = O.OMEGA,
    theta_start_deg: Optional[float] = O.THETA_START_DEG,
    theta_end_deg: Optional[float] = O.THETA_END_DEG,
    n_theta: int = O.N_THETA,
    motion_file: Optional[Path] = O.MOTION_FILE,
    medium: str = _MEDIUM,
    density_kg_m3: Optional[float] = _DENSITY,
    friction_deg: Optional[float] = _FRICTION,
    dilatancy: str = _DILATANCY,
    dp_match: str = _DP_MATCH,
    rheology: str = _RHEOLOGY,
    calibration_bed: str = _CAL_BED,
    boundary: str = _BOUNDARY,
    quick: bool = _QUICK,
    dx_mm: Optional[float] = _DX,
    cfl: float = typer.Option(0.2, help="Courant number of the time step."),
    channel_width_cm: Optional[float] = _CHANNEL,
    wall_friction_deg: Optional[float] = _WALL_FRICTION,
    leg_friction_deg: Optional[float] = _LEG_FRICTION,
    bed_pad_cm: Optional[float] = _BED_PAD,
    lowpass_hz: Optional[float] = typer.Option(None, help="Zero-phase Butterworth low-pass of the force record, Hz (default: none)."),
    checkpoint: Optional[Path] = typer.Option(None, help="Checkpoint file: written every minute; a rerun resumes from it."),
    snapshots: int = typer.Option(0, help="Number of particle snapshots to keep (evenly over the motion; those in the simulated contact part)."),
    snapshots_out: Optional[Path] = typer.Option(None, help="Write the snapshots here (.nc)."),
    compare_rft: bool = typer.Option(False, help="Also run RFT and print peak differences and MSE."),
    out: Optional[str] = O.out(),
    plot: Optional[Path] = O.PLOT,
    backend: Backend = _BACKEND,
):
    """SPH forces (Fx, Fz in N; torque in N m) on a leg moving through a granular bed.

    Only the part of the motion where the leg can touch the bed is simulated.
    """
    import numpy as np

    from .. import io, models
    from ..fieldunits import leg_from_field_units, motion_from_field_units
    from ..models import sph as sph_model
    from ..sph import SPHInstabilityError, snapshots_dataset
    from ..sph.solver import check_checkpoint
    from . import err

    # every input and output is checked before the (long) run
    integer("snapshots", snapshots, 0)
    io.check_output(out, "out")
    io.check_plot(plot)
    io.check_output(snapshots_out, "snapshots-out", (".nc",))
    if snapshots_out is not None and not snapshots:
        models.ignored("snapshots-out", "has no effect without --snapshots N (N > 0)")
    if snapshots and snapshots_out is None:
        models.ignored("snapshots", "has no effect without --snapshots-out FILE.nc")
    check_checkpoint(checkpoint)  # not ours: refused, never overwritten (the run's key: later)
    shape = leg_from_field_units(leg.value, leg_file, curvature, length_cm, width_cm)
    motion = motion_from_field_units(leg.value == "foot" and leg_file is None, motion_file, omega,
                                     hip_height_cm, theta_start_deg, theta_end_deg, n_theta)
    model = models.get("sph")
    opts = model.check_options(dict(
        quick=quick, dx_mm=dx_mm, cfl=cfl, lowpass_hz=lowpass_hz, backend=Backend(backend).value,
        boundary=boundary, friction_deg=friction_deg, density_kg_m3=density_kg_m3,
        dilatancy=dilatancy, dp_match=dp_match, rheology=rheology, calibration_bed=calibration_bed,
        thickness_cm=positive("thickness-cm", thickness_cm, "cm"),
        **{k: v for k, v in (("channel_width_cm", channel_width_cm),
                             ("wall_friction_deg", wall_friction_deg),
                             ("leg_friction_deg", leg_friction_deg),
                             ("bed_pad_cm", bed_pad_cm)) if v is not None}))
    sph_model.config(opts)
    sph_model.material(medium, opts)
    if compare_rft and density_kg_m3 is not None:
        raise InputError("compare-rft", "RFT needs the stress coefficients of a Li 2013 medium; "
                                        "your own medium has none")
    traj = motion.trajectory()
    snap_t = np.linspace(0, traj.time[-1] - traj.time[0], snapshots) if snapshots else ()
    runs = []
    try:
        with _progress(f"SPH {shape.name}") as cb:
            ds = model.simulate(shape, motion, medium, **opts, snapshot_times=snap_t,
                                checkpoint=checkpoint, progress=cb, on_run=runs.append)
    except SPHInstabilityError as e:
        _unstable(e)
    res = runs[0] if runs else None
    _resumed(getattr(res, "resumed_from", None))
    io.emit(ds, out)
    if snapshots and snapshots_out is not None:
        if res is None or not res.snapshots:
            models.ignored("snapshots", "the leg never reached the bed: no snapshots to write")
        else:
            io.write_netcdf(snapshots_dataset(res), snapshots_out)
    if compare_rft:
        from ..sph.validation import compare_with_rft

        rft = models.simulate("rft", shape, motion, medium)
        err(json.dumps(compare_with_rft(ds, rft), indent=1))
    if plot is not None:
        from .. import plots

        series = {"SPH": ds}
        if compare_rft:
            series["RFT"] = rft
        plots.forces(series, plot, title=f"SPH, {shape.name}, {medium}")
    if out not in (None, "-"):
        err(f"wrote {out}")


@sph_app.command("bed")
def bed_cmd(medium: str = _MEDIUM, quick: bool = _QUICK, dx_mm: Optional[float] = _DX,
            initial: str = typer.Option("zero", help="Initial stress: zero (settle under gravity) or geostatic."),
            plot: Optional[Path] = typer.Option(None, help="Figure of stress against depth.")):
    """Scene 1: a bed at rest; vertical and lateral stress against depth (JSON on stdout)."""
    from .. import io
    from ..sph import plots, validation

    dx = _dx(dx_mm) or (5e-3 if quick else 2.5e-3)
    io.check_plot(plot)
    r = validation.bed_at_rest(medium, dx=dx, initial=initial, depth=0.06 if quick else 0.1)
    typer.echo(json.dumps({k: (v.tolist() if hasattr(v, "tolist") else v) for k, v in r.items()}))
    if plot:
        plots.bed(r, plot)


@sph_app.command("column")
def column_cmd(aspect: list[float] = typer.Option([0.5, 1.0, 2.0], help="Aspect ratios H/L (repeat)."),
               medium: str = _MEDIUM, quick: bool = _QUICK, dx_mm: Optional[float] = _DX,
               rheology: str = _RHEOLOGY,
               channel_width_cm: Optional[float] = _CHANNEL,
               wall_friction_deg: Optional[float] = _WALL_FRICTION,
               plot: Optional[Path] = typer.Option(None, help="Figure: deposits and run-out vs Lube et al. 2005.")):
    """Scene 2: collapse of 2D granular columns; run-out and final height vs Lube et al. (2005)."""
    from .. import io, models
    from ..models import sph as sph_model
    from ..sph import plots, validation

    dx = _dx(dx_mm) or (4e-3 if quick else 2e-3)
    for a in aspect:
        positive("aspect", a)
    # the side walls and the friction law through the model's own option checks (as sph run)
    opts = models.get("sph").check_options({"channel_width_cm": channel_width_cm,
                                            "wall_friction_deg": wall_friction_deg,
                                            "rheology": rheology})
    cfg = sph_model.config(opts)
    io.check_plot(plot)
    mat = sph_model.material(medium, opts)
    base = 0.06 if quick else 0.1
    walls = dict(channel_width=cfg.channel_width, wall_friction=cfg.wall_friction)
    rows = []
    with _progress("columns") as cb:
        for k, a in enumerate(aspect):
            rows.append(validation.column_collapse(a, mat, base=base, dx=dx, **walls))
            cb(k + 1, len(aspect))
    typer.echo(json.dumps([{k: v for k, v in r.items() if isinstance(v, float)} for r in rows]))
    if plot:
        plots.columns(rows, plot)


@sph_app.command("plate")
def plate_cmd(medium: str = _MEDIUM, density_kg_m3: Optional[float] = _DENSITY,
              friction_deg: Optional[float] = _FRICTION, dilatancy: str = _DILATANCY,
              dp_match: str = _DP_MATCH, rheology: str = _RHEOLOGY, boundary: str = _BOUNDARY,
              calibration_bed: str = _CAL_BED,
              quick: bool = _QUICK, dx_mm: Optional[float] = _DX,
              speed_cm_s: float = typer.Option(1.0, help="Plate speed, cm/s."),
              depth_cm: float = typer.Option(5.0, help="Final depth, cm."),
              bed_pad_cm: Optional[float] = typer.Option(None, "--bed-pad-cm", show_default="the calibration bed, 9.5 cm beside and 7.6 cm below; with --calibration-bed large, that calibration's bed", help="Granular bed beyond the plate's edges and below its deepest point, cm, in [1, 50]; the calibration's bed holds the plate up by 9-13 % (docs/sph.md 'Bed size')."),
              bed_below_cm: Optional[float] = typer.Option(None, "--bed-below-cm", show_default="as --bed-pad-cm", help="Granular bed below the plate's deepest point on its own, cm, in [1, 50] (the width keeps --bed-pad-cm; docs/sph.md 'Bed size')."),
              plot: Optional[Path] = typer.Option(None, help="Figure: stress on the plate vs depth.")):
    """Scene 3: a horizontal plate pushed down; alpha_z(0, pi/2) against Li et al. (2013)."""
    from .. import io
    from ..sph import plots, validation
    from ..sph.api import default_config
    from ..sph.state import bed_pad_m

    positive("speed-cm-s", speed_cm_s, "cm/s")
    positive("depth-cm", depth_cm, "cm")
    pad = None if bed_pad_cm is None else bed_pad_m("bed-pad-cm", bed_pad_cm)
    below = None if bed_below_cm is None else bed_pad_m("bed-below-cm", bed_below_cm)
    io.check_plot(plot)
    dx = default_config(quick, dx=_dx(dx_mm)).dx
    mat = _material(medium, density_kg_m3, friction_deg, dilatancy, dp_match, rheology, dx=dx,
                    calibration_bed=calibration_bed)
    if pad is None:  # the bed the medium's calibration was made in (None: the standard one)
        from ..sph.calibration import plate_bed

        pad = plate_bed(medium, calibration_bed)
    cfg = default_config(quick, dx=dx, boundary=boundary, bed_pad=pad)
    r = validation.plate_push(mat, speed=speed_cm_s * 1e-2, depth=depth_cm * 1e-2, config=cfg, below=below)
    typer.echo(json.dumps({"alpha_z_N_per_cm3": r["alpha_z"] / 1e6,
                           "alpha_z_through_origin_N_per_cm3": r["alpha_z_origin"] / 1e6,
                           "alpha_z_measured_N_per_cm3": (r["alpha_z_measured"] or float("nan")) / 1e6,
                           "alpha_z_rft_fit_N_per_cm3": r["alpha_z_fit"] / 1e6}))
    if plot:
        plots.plate(r, plot)


@sph_app.command("legs")
def legs_cmd(omega: list[float] = typer.Option([0.2], help="Angular speeds, rad/s (repeat; the thesis uses 0.2 ... 1.1)."),
             legs: list[str] = typer.Option(["flat", "c", "reverse-c"], "--leg", help="Legs (repeat)."),
             medium: str = _MEDIUM, quick: bool = _QUICK, dx_mm: Optional[float] = _DX,
             rheology: str = _RHEOLOGY, calibration_bed: str = _CAL_BED,
             n_theta: int = typer.Option(271, help="Output angles."),
             outdir: Path = typer.Option(Path("results/sph"), "--out", "-o", "--outdir", help="Directory for series, metrics and figures."),
             checkpoint_dir: Optional[Path] = typer.Option(None, help="Directory for checkpoints (resume)."),
             backend: Backend = _BACKEND,
             ):
    """Scenes 4-5: the rotating-leg test (SPH vs RFT) for several legs and speeds."""
    from .. import io
    from ..geometry import make_leg
    from ..sph import SPHInstabilityError, plots, validation
    from ..sph.solver import check_checkpoint

    cfg = _config(quick, dx_mm, 0.2, None, Backend(backend).value)
    mat = _material(medium, None, None, rheology=rheology, dx=cfg.dx, calibration_bed=calibration_bed)
    io.check_writable(outdir, "out", directory=True)
    if checkpoint_dir is not None:
        io.check_writable(checkpoint_dir, "checkpoint-dir", directory=True)
    tags = [(name, w, f"{name}_w{w:g}") for name in legs for w in omega]
    for name, _, tag in tags:
        make_leg(name)  # an unknown leg: an error before the first run
        if checkpoint_dir is not None:
            check_checkpoint(checkpoint_dir / f"{tag}.npz")
    outdir.mkdir(parents=True, exist_ok=True)
    metrics = {}
    for name, w, tag in tags:
        ck = checkpoint_dir / f"{tag}.npz" if checkpoint_dir else None
        try:
            with _progress(f"SPH {tag}") as cb:
                r = validation.rotating_leg(make_leg(name), w, mat, quick=quick, config=cfg,
                                            n_theta=n_theta, progress=cb, checkpoint=ck)
        except SPHInstabilityError as e:
            _unstable(e)
        _resumed(json.loads(r["sph"].attrs.get("input", "{}")).get("run", {})
                 .get("resumed_from"))
        io.write(r["sph"], outdir / f"sph_{tag}.nc")
        metrics[tag] = r["metrics"]
        plots.leg_comparison(r["sph"], r["rft"], outdir / f"sph_vs_rft_{tag}.png",
                             title=f"{name} leg, omega = {w:g} rad/s, {medium}")
    io.atomic_write_text(outdir / "metrics.json", json.dumps(metrics, indent=1))
    typer.echo(json.dumps(metrics, indent=1))


@sph_app.command("leg3d")
def leg3d_cmd(medium: str = _MEDIUM, density_kg_m3: Optional[float] = _DENSITY,
              friction_deg: Optional[float] = _FRICTION, calibration_bed: str = _CAL_BED,
              leg: str = typer.Option("flat", help="Leg shape: flat, c or reverse-c (the 7.62 cm chord legs of Li 2013)."),
              dx_mm: float = typer.Option(4.0, "--dx-mm", help="Particle spacing, mm (4: about an hour for poppy LP on one core; the cost grows as dx^-4)."),
              omega: float = typer.Option(1.1, help="Angular speed, rad/s (the 2D validation's 1.1)."),
              slab: Optional[int] = typer.Option(None, help="Plane-strain configuration instead: a slab this many particles thick (>= 4) between two mirror planes."),
              out: Optional[Path] = typer.Option(None, "--out", "-o", help="Write the curves and peaks as JSON here (stdout gets the summary)."),
              plot: Optional[Path] = typer.Option(None, help="Figure: lift and thrust against the leg angle, with the measured curve where there is one."),
              checkpoint: Optional[Path] = typer.Option(None, help="Checkpoint file: written every minute; a rerun with the same options resumes from it (same forces as a run never stopped)."),
              so_far: bool = typer.Option(False, "--so-far", help="Run nothing: the curve and peaks so far of the run (same options) whose --checkpoint is there, stopped or still going."),
              backend: Backend = _BACKEND):
    """A leg of the rotating-leg test in 3D (its real 2.54 cm width; on the CPU on NUMBA_NUM_THREADS threads, same forces on any number; or on an NVIDIA GPU)."""
    from .. import io
    from ..sph import plate3d, plots
    from ..sph.state import SPHConfig
    from ..sph.suite import leg_scores, measured_legs
    from ..units import DEG

    from ..sph.solver import resolve_backend

    plate3d.leg_curvature(leg)  # an unknown leg: an error before any work
    cfg = SPHConfig(dx=_dx(dx_mm), backend=Backend(backend).value)
    resolve_backend(cfg.backend)  # --backend gpu without a GPU: fail before any work
    if slab is not None:
        integer("slab", slab, 4)
    io.check_output(out, "out", (".json",))
    io.check_plot(plot)
    from ..sph.solver import check_checkpoint

    if so_far and checkpoint is None:
        raise InputError("so-far", "needs --checkpoint FILE, the checkpoint of the run to read")
    check_checkpoint(checkpoint)  # never take over a file that is not a checkpoint
    mat = _material(medium, density_kg_m3, friction_deg, calibration_bed=calibration_bed)
    if so_far:
        r = plate3d.leg3d(mat, shape=leg, config=cfg, slab=slab, omega=omega, checkpoint=checkpoint,
                          so_far=True)
    else:
        with _progress(f"SPH 3D {leg} leg, {mat.name}") as cb:
            r = plate3d.leg3d(mat, shape=leg, config=cfg, slab=slab, omega=omega, progress=cb,
                              checkpoint=checkpoint)
        _resumed(r.get("resumed_from"))
    summary = {"medium": mat.name, "leg": leg, "kind": "slab" if slab else "finite", "dx_mm": dx_mm,
               "omega_rad_s": omega, "peak_lift_N": r["peak_lift"],
               "peak_thrust_N": r["peak_thrust"], "particles": r["particles"],
               "steps": r["steps"], "lost": r["lost"], "wall_s": round(r["wall_s"], 1)}
    th = r["theta"] / DEG
    if so_far:  # a partial curve: peaks so far, no scores over the whole stroke
        summary.update(so_far=True, reached_deg=round(r["reached_deg"], 2))
        print(f"so far: the run has reached {r['reached_deg']:.1f} deg; NaN after it", file=sys.stderr)
    else:
        summary.update(leg_scores(mat.name, th, r["Fz"], r["Fx"], omega, leg))
    if out is not None:
        nan = lambda a: [None if v != v else float(v) for v in a]  # noqa: E731  (JSON has no NaN)
        io.atomic_write_text(out, json.dumps(summary | {"theta_deg": th.tolist(), "Fz_N": nan(r["Fz"]),
                                                        "Fx_N": nan(r["Fx"])}, indent=1) + "\n")
    if plot:
        e = measured_legs()
        e = e[(e.medium == mat.name) & (e.leg == leg)]
        meas = {c: (e[e.force == c].theta_deg.values, e[e.force == c].force_N.values) for c in ("Fz", "Fx")}
        plots.leg3d([{"kind": summary["kind"], "theta_deg": th, "Fz_N": r["Fz"], "Fx_N": r["Fx"]}],
                    meas, plot, title=f"{leg} leg, {mat.name}, omega = {omega:g} rad/s, {dx_mm:g} mm particles")
    typer.echo(json.dumps(summary, indent=1))


def register(app: typer.Typer) -> None:
    from . import sph_validate

    sph_validate.register(sph_app)
    app.add_typer(sph_app, name="sph")
