"""``terradyn sph calibrate`` and ``terradyn sph validate``: media from the plate test, and the
model against measurements."""
from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import typer


def _atomic_json(path: Path, data) -> None:
    from ..io import atomic_write_text

    atomic_write_text(path, json.dumps(data, indent=1) + "\n")


def calibrate_cmd(
    medium: list[str] = typer.Option([], "--medium", help="Li 2013 medium to calibrate (repeat; none and no --density-kg-m3: all five)."),
    density_kg_m3: Optional[float] = typer.Option(None, help="A user's medium: bulk density, kg/m^3 (grain density x volume fraction)."),
    alpha_z_n_cm3: Optional[float] = typer.Option(None, "--alpha-z-n-cm3", help="A user's medium: measured plate-test slope alpha_z(0, pi/2), N/cm^3."),
    name: str = typer.Option("custom", help="A user's medium: its name in the output."),
    friction_start_deg: Optional[float] = typer.Option(None, show_default=False, help="First friction angle of the search, deg; the search stops there when its plate slope is already within --tol [default: a Li 2013 medium's shipped calibration (its angle of repose where there is none); a user's medium 30]."),
    dx_mm: float = typer.Option(2.5, "--dx-mm", help="Particle spacing of the plate test, mm (the resolution the medium will run at; 2.5 is the production resolution, docs/sph.md)."),
    youngs_mpa: float = typer.Option(0.25, "--youngs-mpa", help="Young's modulus of the SPH material, MPa (numerical stiffness; at friction angles above ~40 deg the plate test needs >= 1 MPa, docs/sph.md)."),
    tol: float = typer.Option(0.03, help="Relative tolerance on the plate slope."),
    realizations: int = typer.Option(5, help="Plate runs averaged per friction angle (single runs scatter by about 10 %)."),
    starts: str = typer.Option("phase", help="Where those runs start: 'phase' (spread over one particle spacing, so the plate meets the particle lattice at that many phases, as the shipped production calibrations) or 'nm' (10 nm apart from the standard start, as the calibrations before 2026-12-07; at 2.5 mm the standard start of 0.3 mm glass CP reads about 4 % high: docs/sph.md 'Run-to-run scatter')."),
    max_evals: int = typer.Option(6, help="Most friction angles tried per medium."),
    plate_bed_pad_cm: Optional[float] = typer.Option(None, "--plate-bed-pad-cm", show_default="the calibration bed, 9.5 cm beside and 7.6 cm below", help="Granular bed beyond the plate's edges and below its deepest point, cm, in [1, 50] (docs/sph.md 'Bed size')."),
    leg_friction_deg: Optional[float] = typer.Option(None, "--leg-friction-deg", help="Grain-plate friction angle of the plate, deg, in [0, 60]: calibrate for a plate (and legs) of that measured friction (default: none, a rough no-slip plate, as the shipped calibrations; below about 20 deg the plate bears less: docs/sph.md 'Grain-leg friction')."),
    out: Optional[Path] = typer.Option(None, "--out", "-o", help="Write the calibration JSON here (default: stdout)."),
    store: Optional[Path] = typer.Option(None, "--store", show_default="OUT's name with .runs in place of .json, beside it, when --out is given; else none", help="Directory that keeps each finished plate run: the same command started again after an interruption reads them and goes on from there."),
):
    """Calibrate the SPH friction angle of a medium on its plate test (Li 2013 Table S3).

    The plate is pushed straight down in the same 2D SPH set-up the model runs in; the
    friction angle is searched until its stress-depth slope matches the measured one. Leg
    forces are never used. The shipped production calibration is this command with its
    defaults (2.5 mm, five runs started at as many lattice phases) for each medium, merged
    by `python benchmarks/sph_calibration_merge.py` (docs/sph.md). A Li 2013 medium starts at
    its shipped angle, so checking a calibration costs one plate test when that angle holds.
    """
    import datetime
    import platform

    from .. import __version__
    from ..errors import InputError, in_range, integer, positive
    from ..media import MEDIA
    from ..sph.calibration import PLATE_TEST, calibrate_friction, start_offsets
    from ..sph.materials import from_medium, from_properties
    from ..sph.state import SPHConfig, bed_pad_m
    from ..units import DEG, N_PER_CM3
    from . import err

    dx = in_range("dx-mm", dx_mm, 1.0, 20.0, "mm") * 1e-3
    if friction_start_deg is not None:
        in_range("friction-start-deg", friction_start_deg, 10, 60, "deg")
    integer("realizations", realizations, 1)
    start_offsets(realizations, dx, starts)  # the starts and their number, before any work
    youngs = in_range("youngs-mpa", youngs_mpa, 0.05, 100.0, "MPa") * 1e6
    integer("max-evals", max_evals, 2)
    bed_pad = None if plate_bed_pad_cm is None else bed_pad_m("plate-bed-pad-cm", plate_bed_pad_cm)
    leg_friction = (None if leg_friction_deg is None
                    else in_range("leg-friction-deg", leg_friction_deg, 0.0, 60.0, "deg") * DEG)
    config = (None if bed_pad is None and leg_friction is None
              else SPHConfig(dx=dx, bed_pad=bed_pad, leg_friction=leg_friction))
    if out is not None:
        from ..io import check_output

        check_output(out, "out", (".json",))
        if store is None:
            store = out.with_suffix(".runs")
    if store is not None:
        from ..io import check_writable

        check_writable(store, "store", directory=True)
    jobs = []
    if density_kg_m3 is not None or alpha_z_n_cm3 is not None:
        if medium:
            raise InputError("medium", "give either --medium or a user's medium "
                                       "(--density-kg-m3 and --alpha-z-n-cm3), not both")
        if density_kg_m3 is None or alpha_z_n_cm3 is None:
            raise InputError("density-kg-m3" if density_kg_m3 is None else "alpha-z-n-cm3",
                             "a user's medium needs both --density-kg-m3 and --alpha-z-n-cm3")
        positive("alpha-z-n-cm3", alpha_z_n_cm3, "N/cm^3")
        start = 30.0 if friction_start_deg is None else friction_start_deg
        jobs.append((from_properties(name, density_kg_m3, start, youngs=youngs),
                     alpha_z_n_cm3 * N_PER_CM3))
    else:
        for m in medium or list(MEDIA):
            if m not in MEDIA or MEDIA[m].alpha_z_plate is None:
                raise InputError("medium", f"unknown value {m!r}; allowed: "
                                           + ", ".join(k for k in MEDIA if MEDIA[k].alpha_z_plate))
            # the search starts where the shipped calibration found it (the repose angle where
            # there is none): one or two evaluations instead of four to six at a new resolution
            start = friction_start_deg
            if start is None:
                start = from_medium(m).friction / DEG
            jobs.append((from_medium(m, friction_deg=start, youngs=youngs), MEDIA[m].alpha_z_plate))
    result = {"_meta": {"what": "SPH friction angles calibrated on the plate test (terradyn sph calibrate)",
                        "plate_test": PLATE_TEST | ({} if bed_pad is None else {"bed_pad_m": bed_pad})
                        | ({} if leg_friction is None else {"leg_friction_deg": leg_friction_deg}),
                        "dx_m": dx, "realizations": realizations, "starts": starts,
                        **({} if store is None else {"run_store": str(store)}),
                        "terradyn_version": __version__,
                        "created": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
                        "machine": platform.platform()}}
    for mat, target in jobs:
        err(f"calibrating {mat.name}: measured alpha_z = {target / N_PER_CM3:g} N/cm^3")
        cal = calibrate_friction(mat, target, dx=dx, tol=tol, realizations=realizations,
                                 max_evals=max_evals, config=config, starts=starts, store=store,
                                 report=lambda p, a: err(f"  phi = {p:.2f} deg -> alpha_z = {a:.4f} N/cm^3"))
        result[mat.name] = cal.describe() | {"density_kg_m3": mat.density, "youngs_Pa": mat.youngs,
                                             "dp_match": mat.dp_match}
        if not cal.converged:
            err(f"  not converged ({cal.note}): best phi = {cal.friction_deg:.2f} deg")
    if out is None:
        typer.echo(json.dumps(result, indent=1))
    else:
        _atomic_json(out, result)
        err(f"wrote {out}")




def validate_cmd(
    out: Path = typer.Option(..., "--out", "-o", help="Directory for validation.json and the figures."),
    quick: bool = typer.Option(False, "--quick", help="4 mm particles, one column (a = 1), the rig's 3 x 5 subset, the flat leg only."),
    scene: list[str] = typer.Option([], "--scene", help="Scenes to run (repeat): bed, column, plate, rig, legs (default: all)."),
    medium: list[str] = typer.Option([], "--medium", help="Media for plate, rig and legs (repeat; default: the five of Li 2013, legs only where Fig. S5 has curves)."),
    dx_mm: Optional[float] = typer.Option(None, "--dx-mm", help="Particle spacing, mm (default: 2.5, the production resolution; --quick 4)."),
    omega: float = typer.Option(1.1, help="Angular speed of the leg tests, rad/s (1.1 is 5.5 x fewer steps than 0.2; the rate check is in docs/sph.md)."),
    realizations: Optional[int] = typer.Option(None, show_default="3; --quick 1", help="Runs per leg test (1..20), averaged: the measured curves are means over trials, and single runs scatter by 1-5 % with peaks biased high (docs/sph.md); each run's peak and the standard error go into validation.json."),
    rheology: str = typer.Option("constant", "--rheology", help="Friction law of the column, plate, rig and leg scenes: constant (rate-independent) or mu-i (Jop et al. 2006's mu(I) on each medium's calibrated angle; docs/sph.md)."),
    bed_pad_cm: Optional[float] = typer.Option(None, "--bed-pad-cm", show_default="6", help="Leg tests: granular bed beyond the leg's path below the surface, cm, in [1, 50] (docs/sph.md 'Bed size')."),
    calibration_bed: str = typer.Option("standard", "--calibration-bed", help="Which shipped friction calibration the media take: standard (plate in the 9.5 cm calibration bed) or large (plate in a bed where its slope has settled; the plate scene then runs in that bed). docs/sph.md 'Bed size'."),
    leg_friction_deg: Optional[float] = typer.Option(None, "--leg-friction-deg", help="Grain-leg friction angle of the plate, rig and leg scenes, deg, in [0, 60]: a measured grain-surface friction (default: none, a rough no-slip leg; docs/sph.md 'Grain-leg friction')."),
):
    """Run the SPH validation scenes and compare with measurements: validation.json (quantity,
    ours, reference, source, difference, verdict) and figures in OUT.

    Each finished leg run is kept in OUT/runs (the longest part: hours at the production
    resolution); rerunning the same command after an interruption reads those and resumes
    the run it was in from its checkpoint.

    Exit code 0 whether checks pass or fail (the JSON says which); 2 for bad input.
    """
    from ..errors import InputError, choice, in_range
    from ..sph import suite
    from ..sph.state import bed_pad_m
    from . import err

    for s in scene:  # before the output folder is made
        choice("scene", s, list(suite.SCENES))
    dx = None if dx_mm is None else in_range("dx-mm", dx_mm, 1.0, 10.0, "mm") * 1e-3
    in_range("omega", omega, 0.01, 10.0, "rad/s")
    pad = None if bed_pad_cm is None else bed_pad_m("bed-pad-cm", bed_pad_cm)
    leg_friction = None
    if leg_friction_deg is not None:
        from ..units import DEG

        leg_friction = in_range("leg-friction-deg", leg_friction_deg, 0.0, 60.0, "deg") * DEG
        if scene and not set(scene) & {"plate", "rig", "legs"}:
            from ..models import ignored

            ignored("leg-friction-deg", "applies to the plate, rig and leg scenes only, and "
                                        "--scene includes none of them")
    if realizations is not None:
        suite.check_realizations(realizations)  # before the output folder is made
    from ..sph.materials import RHEOLOGIES

    choice("rheology", rheology, list(RHEOLOGIES))
    from ..errors import renamed

    with renamed(calibration_bed="calibration-bed"):  # before the output folder is made
        suite.check_media(tuple(scene) or suite.SCENES, medium or None, calibration_bed)
    if realizations is not None and realizations > 1 and scene and "legs" not in scene:
        from ..models import ignored

        ignored("realizations", "applies to the leg tests only, and --scene does not include legs")
    if pad is not None and scene and "legs" not in scene:
        from ..models import ignored

        ignored("bed-pad-cm", "applies to the leg tests only, and --scene does not include legs")
    if out.exists() and not out.is_dir():
        raise InputError("out", f"{out} exists and is not a directory")
    out.mkdir(parents=True, exist_ok=True)
    res = suite.validate(quick=quick, scenes=tuple(scene) or suite.SCENES, media=medium or None,
                         dx=dx, omega=omega, progress=lambda m: err(f"[dim]{m}[/]"),
                         figures_dir=out, realizations=realizations, rheology=rheology,
                         store=out / "runs", bed_pad=pad, calibration_bed=calibration_bed,
                         leg_friction=leg_friction)
    res["summary"] = suite.summary(res)
    _atomic_json(out / "validation.json", res)
    for c in res["checks"]:
        mark = {"pass": "[green]pass[/]", "fail": "[red]fail[/]"}.get(c["verdict"], c["verdict"])
        ref = "-" if c["reference"] is None else f"{c['reference']:.4g}"
        err(f"{mark}  {c['quantity']}: {c['ours']:.4g} (ref {ref}; {c['tolerance']})")
    s = res["summary"]
    err(f"{s['pass']} of {s['total']} checks pass; wrote {out / 'validation.json'}")


def register(sph_app: typer.Typer) -> None:
    sph_app.command("calibrate")(calibrate_cmd)
    sph_app.command("validate")(validate_cmd)
