"""``terradyn study``: the brief's studies, writing datasets and figures to a folder."""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer

from . import sub_app

study_app = sub_app(help="Run the brief's studies (datasets + figures into --out).",
                        no_args_is_help=True)


def _progress_run(names, fn):
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

    from . import err

    with Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                  TimeElapsedColumn(), console=Console(stderr=True)) as p:
        task = p.add_task("studies", total=len(names))
        started = []

        def step(name):
            if started:
                p.advance(task)
            started.append(name)
            p.update(task, description=f"study: {name}")

        result = fn(step)
        p.update(task, completed=len(names), description="studies done")
    err("[green]done[/]")
    return result


@study_app.command("all")
def all_(out: Path = typer.Option(Path("results"), "--out", "-o", help="Output folder."),
         quick: bool = typer.Option(False, help="Coarser grids (seconds).")):
    """Every study: interpolators, three legs, frames, foot, RFT vs Li 2013 experiments."""
    from .. import studies

    _check(out)
    names = list(studies.STUDIES)
    _progress_run(names, lambda step: studies.run_all(out, progress=step, quick=quick))
    typer.echo(str(out))


OUT = typer.Option(Path("results"), "--out", "-o", help="Output folder.")


def _check(out: Path, medium: str | None = None, alpha: str | None = None, interp: str | None = None,
           zeta: float | None = None, n_theta: int | None = None, elements: int | None = None) -> None:
    """Every input of a study checked before its work: the folder, the medium and model
    options, the sizes."""
    from .. import io, models
    from ..errors import integer

    io.check_writable(out, "out", directory=True)
    if n_theta is not None:
        integer("n-theta", n_theta, 2)
    if elements is not None:
        integer("elements", elements, 2)
    if n_theta is not None and elements is not None:
        from ..fieldunits import check_rft_size

        check_rft_size(n_theta, elements)
    if medium is not None:
        opts = models.get("rft").check_options({"alpha": alpha, "zeta": zeta,
                                                "interp": interp if alpha == "table" else None})
        from ..models.rft import stress_model_of

        stress_model_of(medium, **opts)
MEDIUM = typer.Option("3 mm glass CP", help="Medium (see `terradyn rft --help`).")
ALPHA = typer.Option("table", help="Stress coefficients: fit, generic or table.")


@study_app.command("interp")
def interp(out: Path = OUT, map_medium: str = typer.Option("3 mm glass CP", help="Medium of the alpha maps.")):
    """Hold-out comparison of the five interpolators and the fit (all media)."""
    from .. import studies

    _check(out, map_medium, "fit")
    studies.interp_study(out, map_medium)
    typer.echo(str(out))


@study_app.command("legs")
def legs(out: Path = OUT, medium: str = MEDIUM, alpha: str = ALPHA,
         interp: str = typer.Option("linear", help="Interpolator for --alpha table."),
         zeta: Optional[float] = typer.Option(None, help="zeta for --alpha generic."),
         n_theta: int = typer.Option(271, help="Number of angles."),
         elements: int = typer.Option(100, help="Elements per leg.")):
    """Rotating-leg forces for the flat, C and reverse C legs, each alone and together."""
    from .. import studies

    if alpha != "table" and interp != "linear":
        from ..models import ignored

        ignored("interp", f"has no effect without --alpha table (alpha is {alpha!r})")
    _check(out, medium, alpha, interp, zeta, n_theta, elements)
    studies.legs_study(out, medium, alpha, interp, zeta, n_theta, elements)
    typer.echo(str(out))


@study_app.command("frames")
def frames(out: Path = OUT, medium: str = MEDIUM, alpha: str = ALPHA,
           theta_deg: list[float] = typer.Option([-90, -60, -30, 0, 30, 60], help="Angles to show (repeat the option).")):
    """Frames of each leg rotating through the bed with element force arrows."""
    from .. import studies
    from ..errors import finite_array

    _check(out, medium, alpha)
    finite_array("theta-deg", theta_deg)
    studies.frames_study(out, medium, alpha, tuple(theta_deg))
    typer.echo(str(out))


@study_app.command("foot")
def foot(out: Path = OUT, medium: str = typer.Option("poppy LP", help="Medium."),
         alpha: str = typer.Option("fit", help="Stress coefficients: fit, generic or table."),
         length_cm: list[float] = typer.Option(list(range(25, 34)), help="Foot lengths, cm (repeat the option)."),
         max_deg: float = typer.Option(3.0, help="Largest rotation, deg."),
         width_cm: float = typer.Option(8.5, help="Foot width, cm.")):
    """Human-sized foot: forces against rotation for several lengths."""
    from .. import studies
    from ..errors import positive

    _check(out, medium, alpha)
    for L in length_cm:
        positive("length-cm", L, "cm")
    positive("max-deg", max_deg, "deg")
    positive("width-cm", width_cm, "cm")
    studies.foot_study(out, tuple(length_cm), medium, alpha, max_deg, 61, width_cm)
    typer.echo(str(out))


@study_app.command("experiment")
def experiment(out: Path = OUT):
    """RFT (generic x fitted zeta) vs the measured curves of Li 2013 Fig. S12."""
    from .. import studies

    _check(out)
    studies.experiment_study(out)
    typer.echo(str(out))


def register(app: typer.Typer) -> None:
    app.add_typer(study_app, name="study")
