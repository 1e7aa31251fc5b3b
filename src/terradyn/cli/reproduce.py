"""``terradyn reproduce``: the thesis reproduced as one HTML report (``DIR/index.html``) and
``DIR/report.json``."""
from __future__ import annotations

from pathlib import Path

import typer


def reproduce_cmd(
    out: Path = typer.Option(Path("results"), "--out", "-o", help="Output folder (index.html, report.json, parts/)."),
    quick: bool = typer.Option(False, "--quick", help="Coarse grids, flat leg only in the DDDAS speed study, "
                                                      "1000 particles (minutes on 2 cores)."),
    full: bool = typer.Option(False, "--full", help="Also run the SPH validation scenes afresh (hours) instead of "
                                                    "reading the shipped result files."),
    regenerate: bool = typer.Option(False, help="With --full: rebuild the shipped SPH training set "
                                                "(datasets/sph_legs_speeds.toml, hours) into OUT/datasets and use it."),
    part: list[str] = typer.Option([], "--part", help="Only these parts (repeat); default all."),
):
    """The thesis reproduced: every claim a card with our figure, the published number and
    its source, our number, the tolerance and a computed verdict. Parts are cached by the
    hash of their inputs: a rerun redoes only what changed."""
    from ..errors import InputError, choice
    from ..io import check_writable
    from ..report import PART_NAMES, reproduce
    from . import err

    if quick and full:
        raise InputError("quick", "give --quick or --full, not both")
    for p in part:
        choice("part", p, list(PART_NAMES))
    check_writable(out, "out", directory=True)
    tier = "quick" if quick else "full" if full else "standard"
    report = reproduce(out, tier, parts=part or None, regenerate=regenerate,
                       progress=lambda m: err(f"reproduce: {m}"))
    s = report["summary"]
    err(f"[green]done[/]: {s['n_cards']} claims, " + ", ".join(f"{v} {k}" for k, v in s["cards"].items())
        + f"; open {(Path(out) / 'index.html').resolve().as_uri()}")
    typer.echo(str(Path(out) / "index.html"))


def register(app: typer.Typer) -> None:
    app.command("reproduce")(reproduce_cmd)
