"""``terradyn mujoco``: granular terrain (3D RFT) for MuJoCo robots - the walking-robot demo
and a single foot pressed into the bed."""
from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path
from typing import Optional

import typer

from . import sub_app

mj_app = sub_app(help="Granular terrain (3D RFT) for MuJoCo robot models: demo robot, foot press.")

_MEDIA_HELP = "poppy LP, poppy CP, 0.3 mm glass LP, 0.3 mm glass CP, 3 mm glass CP"


def _require_mujoco():
    import os

    from ..errors import InputError

    os.environ.setdefault("MUJOCO_GL", "egl")  # offscreen GL: must be set before mujoco is imported
    try:
        import mujoco  # noqa: F401
    except ImportError:
        raise InputError("mujoco", "the 'mujoco' package is not installed: pip install 'terradyn[mujoco]'") from None


def _plot_study(results, path) -> None:
    """Bar chart: speed (cm/s) against leg shape, one group per medium."""
    import matplotlib.pyplot as plt
    import numpy as np

    media = list(dict.fromkeys(r.medium for r in results))
    legs = list(dict.fromkeys(r.leg for r in results))
    fig, ax = plt.subplots(figsize=(5.5, 3.6), constrained_layout=True)
    wbar = 0.8 / len(media)
    for j, med in enumerate(media):
        vals = [next(r.speed_m_s for r in results if r.leg == lg and r.medium == med) * 100 for lg in legs]
        ax.bar(np.arange(len(legs)) + (j - (len(media) - 1) / 2) * wbar, vals, wbar, label=med)
    ax.set_xticks(np.arange(len(legs)), [{"c": "C", "flat": "flat", "reverse-c": "reverse C"}.get(x, x) for x in legs])
    ax.set_xlabel("leg shape")
    ax.set_ylabel("speed along the path (cm/s)")
    ax.axhline(0, color="k", lw=0.6)
    ax.set_title("Demo hexapod on granular media (3D RFT in MuJoCo)", fontsize=10)
    ax.legend(title="medium", fontsize=8)
    fig.savefig(path, dpi=150)
    plt.close(fig)


def _write_gif(path: Path, frames, fps: float) -> None:
    from PIL import Image

    imgs = [Image.fromarray(f) for f in frames]
    tmp = path.with_name(f".{path.name}.tmp.gif")
    try:
        imgs[0].save(tmp, save_all=True, append_images=imgs[1:], duration=int(1000 / fps), loop=0)
        tmp.replace(path)
    finally:
        tmp.unlink(missing_ok=True)


@mj_app.command("demo")
def demo_cmd(
    out: Path = typer.Option(..., "--out", "-o", help="Directory for the table, figure, GIF and MJCF files."),
    robot: str = typer.Option("hexapod", "--robot", help="Demo robot (hexapod: six rotating arc legs, RHex-like)."),
    leg: list[str] = typer.Option([], "--leg", help="Leg shapes to run (repeat): c, flat, reverse-c (default: all three)."),
    medium: list[str] = typer.Option([], "--medium", help=f"Media (repeat): {_MEDIA_HELP} (default: poppy LP, 3 mm glass CP)."),
    duration_s: float = typer.Option(5.0, "--duration-s", help="Simulated time per run, s."),
    settle_s: float = typer.Option(1.5, "--settle-s", help="Start-up time left out of the speed, s."),
    gif: bool = typer.Option(True, "--gif/--no-gif", help="Render a GIF offscreen (MUJOCO_GL=egl or osmesa)."),
    gif_duration_s: float = typer.Option(3.0, "--gif-duration-s", help="Simulated time in the GIF, s."),
    gif_width: int = typer.Option(320, "--gif-width", help="GIF width, pixels (height 3/4 of it)."),
    dynamic_lambda: Optional[float] = typer.Option(None, "--dynamic-lambda", help="Dynamic-RFT lambda (e.g. 1.1; default: quasi-static RFT)."),
):
    """Walk the demo hexapod with C, flat and reverse-C legs on granular media (3D RFT ground
    in MuJoCo): speed table (mujoco_demo.csv/.json), figure (mujoco_demo_speed.png), GIF
    (mujoco_demo.gif, offscreen; skipped with the reason if no GL is available here) and the
    robots' MJCF files, all in OUT."""
    from ..errors import InputError, choice, in_range, integer, positive
    from ..io import atomic_write_text, check_writable
    from ..media import MEDIA
    from . import err

    _require_mujoco()
    from ..adapters import mujoco_demo as md

    choice("robot", robot, md.ROBOTS)
    legs = tuple(leg) or md.LEG_SHAPES
    media = tuple(medium) or md.DEMO_MEDIA
    for x in legs:
        choice("leg", x, md.LEG_SHAPES)
    for x in media:
        choice("medium", x, list(MEDIA))
    positive("duration-s", duration_s, "s")
    in_range("settle-s", settle_s, 0.0, 0.9 * duration_s, "s (below 0.9 x --duration-s)")
    positive("gif-duration-s", gif_duration_s, "s")
    integer("gif-width", gif_width, 16)
    if dynamic_lambda is not None:
        in_range("dynamic-lambda", dynamic_lambda, 0.0, 10.0)
    if out.exists() and not out.is_dir():
        raise InputError("out", f"{out} exists and is not a directory")
    check_writable(out, "out", directory=True)
    out.mkdir(parents=True, exist_ok=True)

    for x in legs:
        atomic_write_text(out / f"{robot}_{x}.xml", md.hexapod_mjcf(x))
    results = md.walk_study(legs, media, duration_s, settle_s, progress=lambda m: err(f"[dim]{m}[/]"),
                            dynamic_lambda=dynamic_lambda or None)
    rows = md.study_table(results)
    csv = ["leg,medium,speed_cm_s,speed_body_lengths_s,stride_cm,mean_torso_height_cm,heading_change_deg,"
           "max_tilt_deg,sim_to_wall,terrain_share_of_wall"]
    for r in results:
        csv.append(f"{r.leg},{r.medium},{r.speed_m_s * 100:.4g},{r.speed_body_lengths_s:.4g},{r.stride_m * 100:.4g},"
                   f"{r.mean_torso_height_m * 100:.4g},{r.heading_change_deg:.3g},{r.max_tilt_deg:.3g},"
                   f"{r.sim_to_wall:.4g},{r.terrain_s / r.wall_s:.3g}")
    atomic_write_text(out / "mujoco_demo.csv", "\n".join(csv) + "\n")
    _plot_study(results, out / "mujoco_demo_speed.png")
    gif_info = {"written": False, "reason": "--no-gif"}
    if gif:
        fps = 20.0
        frames, msg = md.render_frames(legs[0], media[0], gif_duration_s, width=gif_width,
                                       height=gif_width * 3 // 4, fps=fps,
                                       dynamic_lambda=dynamic_lambda or None)
        ok = frames is not None
        if ok:
            _write_gif(out / "mujoco_demo.gif", frames, fps)
        gif_info = {"written": ok, "leg": legs[0], "medium": media[0], ("info" if ok else "reason"): msg}
        err(f"GIF: {msg}" if ok else f"[yellow]GIF skipped:[/] {msg}")
    ordering = {m: [r.leg for r in sorted((r for r in results if r.medium == m), key=lambda r: -r.speed_m_s)]
                for m in media}
    doc = {"robot": robot, "robot_parameters": asdict(md.HEXAPOD), "dynamic_lambda": dynamic_lambda, "runs": rows,
           "speed_ordering_fastest_first": ordering, "gif": gif_info,
           "li2013_comparison": md.LI2013_NOTE}
    atomic_write_text(out / "mujoco_demo.json", json.dumps(doc, indent=1) + "\n")
    for m, o in ordering.items():
        err(f"{m}: fastest to slowest: {', '.join(o)}")
    err(f"wrote {out}/mujoco_demo.csv, .json, _speed.png" + (", .gif" if gif_info["written"] else ""))


@mj_app.command("press")
def press_cmd(
    load_n: float = typer.Option(20.0, "--load-n", help="Vertical load on the foot, N (its weight comes on top)."),
    medium: str = typer.Option("3 mm glass CP", "--medium", help=f"Medium: {_MEDIA_HELP}."),
    length_cm: float = typer.Option(6.0, "--length-cm", help="Foot length, cm."),
    width_cm: float = typer.Option(4.0, "--width-cm", help="Foot width, cm."),
    thickness_cm: float = typer.Option(0.4, "--thickness-cm", help="Foot thickness, cm."),
    mass_kg: float = typer.Option(0.2, "--mass-kg", help="Foot mass, kg."),
    ramp_s: float = typer.Option(3.0, "--ramp-s", help="Time over which the load rises from 0, s."),
    hold_s: float = typer.Option(0.5, "--hold-s", help="Time the full load is held, s."),
):
    """Press a flat box foot into the bed (MuJoCo + 3D RFT) and print its sinkage against the
    closed-form RFT equilibrium depth (JSON on stdout, depths in cm)."""
    from ..errors import choice, in_range, positive
    from ..media import MEDIA

    _require_mujoco()
    from ..adapters import mujoco_demo as md

    choice("medium", medium, list(MEDIA))
    size = tuple(positive(k, v, "cm") / 100 for k, v in (("length-cm", length_cm), ("width-cm", width_cm),
                                                          ("thickness-cm", thickness_cm)))
    res = md.press_foot(medium, in_range("load-n", load_n, 0.0, 1e6, "N"), size, positive("mass-kg", mass_kg, "kg"),
                        in_range("ramp-s", ramp_s, 0.0, 60.0, "s"), in_range("hold-s", hold_s, 0.0, 60.0, "s"))
    exp = res["expected_depth_m"]
    typer.echo(json.dumps({"medium": medium, "load_N": load_n, "weight_N": res["weight_N"],
                           "sinkage_cm": res["final_depth_m"] * 100,
                           "closed_form_cm": None if exp is None else exp * 100,
                           "relative_difference": res["relative_error"]}, indent=1))


def register(app: typer.Typer) -> None:
    app.add_typer(mj_app, name="mujoco")
