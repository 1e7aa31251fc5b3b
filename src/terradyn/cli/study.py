"""``terradyn study``: the brief's studies, writing datasets and figures to a folder."""
from __future__ import annotations

from pathlib import Path

import typer

study_app = typer.Typer(help="Run the brief's studies (datasets + figures into --out).",
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

    names = list(studies.STUDIES)
    _progress_run(names, lambda step: studies.run_all(out, progress=step, quick=quick))
    typer.echo(str(out))


def _one(name: str, doc: str):
    def cmd(out: Path = typer.Option(Path("results"), "--out", "-o", help="Output folder.")):
        from .. import studies

        studies.STUDIES[name](out)
        typer.echo(str(out))

    cmd.__doc__ = doc
    study_app.command(name)(cmd)


_one("interp", "Hold-out comparison of the five interpolators and the fit (all media).")
_one("legs", "Rotating-leg forces for the flat, C and reverse C legs.")
_one("frames", "Frames of each leg with element force arrows.")
_one("foot", "Human-sized foot, lengths 25-33 cm.")
_one("experiment", "RFT vs the measured curves of Li 2013 Fig. S12.")


def register(app: typer.Typer) -> None:
    app.add_typer(study_app, name="study")
