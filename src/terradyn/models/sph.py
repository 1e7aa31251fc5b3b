"""SPH (elasto-plastic Drucker-Prager bed, :mod:`terradyn.sph`) as a registered model.

This file imports nothing heavy at load: Numba and the solver load when a run starts.
"""
from __future__ import annotations

import math

from ..errors import InputError
from ..units import CM
from . import Model, Option

#: Largest particle spacing accepted, mm (coarser beds hold too few particles).
DX_MM_MAX = 10.0

OPTIONS = (
    Option("quick", bool, False, help="Coarse resolution (4 mm particles) for tests and previews."),
    Option("dx_mm", float, None, "mm", 0, DX_MM_MAX, lo_open=True, help="Particle spacing (default 2.5; quick 4)."),
    Option("hdx", float, None, "", 0, None, lo_open=True, help="Smoothing length / spacing."),
    Option("cfl", float, None, "", 0, 1, lo_open=True, help="Courant number of the time step."),
    Option("av_alpha", float, None, "", 0, None, help="Artificial viscosity alpha."),
    Option("av_beta", float, None, "", 0, None, help="Artificial viscosity beta."),
    Option("wall_layers", int, None, "", 1, None, help="Layers of wall particles."),
    Option("noslip", bool, None, help="No-slip walls."),
    Option("settle_time_s", float, None, "s", 0, None, help="Settling time before the motion."),
    Option("lowpass_hz", float, None, "Hz", 0, None, lo_open=True, help="Zero-phase low-pass of the force record."),
    Option("thickness_cm", float, None, "cm", 0, None, lo_open=True, help="Leg thickness (default 0.64)."),
    Option("bed_width_cm", float, None, "cm", 0, None, lo_open=True, help="Bed width (default: from the path)."),
    Option("bed_depth_cm", float, None, "cm", 0, None, lo_open=True, help="Bed depth (default: from the path)."),
    Option("bed_pad_cm", float, None, "cm", 1, 50,
           help="Bed beyond the leg's path below the surface (default 6; quick 3; docs/sph.md 'Bed size')."),
    Option("boundary", str, None, choices=("resolved", "guard"), help="Leg boundary model (default resolved)."),
    Option("friction_deg", float, None, "deg", 0, 80, lo_open=True, help="Friction angle (default: the medium's shipped plate-test calibration, else its repose angle)."),
    Option("density_kg_m3", float, None, "kg/m^3", 0, None, lo_open=True, help="Your own medium's bulk density (needs friction_deg)."),
    Option("backend", str, None, choices=("cpu", "gpu", "auto"), help="Kernels (default cpu)."),
    Option("channel_width_cm", float, None, "cm", 0, None, lo_open=True,
           help="Side walls of a quasi-2D channel this far apart, with Coulomb friction (default: "
                "none, plane strain)."),
    Option("wall_friction_deg", float, None, "deg", 0, 60,
           help="Grain-wall friction angle of the side walls (default: the medium's friction "
                "angle; needs channel_width_cm)."),
    Option("leg_friction_deg", float, None, "deg", 0, 60,
           help="Grain-leg friction angle: Coulomb slip of the grains on the leg's surface "
                "(default: none, a rough no-slip leg; docs/sph.md 'Grain-leg friction')."),
    Option("dilatancy", str, None, choices=("none", "bolton"),
           help="Flow rule (default none; bolton: a CP medium dilates until its LP packing, Bolton 1986)."),
    Option("rheology", str, None, choices=("constant", "mu-i"),
           help="Friction law (default constant: rate-independent; mu-i: Jop et al. 2006's mu(I) "
                "on the medium's calibrated friction angle, a Li 2013 medium only)."),
    Option("dp_match", str, None, choices=("plane-strain", "bui2008"),
           help="Drucker-Prager cone matched to the friction angle (default plane-strain; bui2008: "
                "the former cone, which mobilises less friction; a named medium then uses its "
                "repose angle unless friction_deg is given)."),
    Option("calibration_bed", str, None, choices=("standard", "large"),
           help="Plate bed of a Li 2013 medium's shipped calibration (default standard: 9.5 cm "
                "beside the plate; large: a bed where the plate's slope has settled, 0.3-2.7 deg "
                "steeper friction; docs/sph.md 'Bed size')."),
)
_CFG = {"hdx": "hdx", "cfl": "cfl", "av_alpha": "av_alpha", "av_beta": "av_beta",
        "wall_layers": "wall_layers", "noslip": "noslip", "boundary": "boundary",
        "settle_time_s": "settle_time", "lowpass_hz": "lowpass_hz", "backend": "backend"}


def _dx(opts: dict) -> float:
    """The particle spacing (m) the checked options ask for."""
    from ..sph import FULL_DX, QUICK_DX

    return opts["dx_mm"] * 1e-3 if "dx_mm" in opts else (QUICK_DX if opts.get("quick") else FULL_DX)


def config(opts: dict, field=lambda k: k.replace("_", "-")):
    """The :class:`terradyn.sph.SPHConfig` of checked options (the GPU checked usable)."""
    from ..sph import SPHConfig
    from ..sph.solver import resolve_backend

    dx = _dx(opts)
    kw = {c: opts[k] for k, c in _CFG.items() if k in opts}
    if "wall_friction_deg" in opts and "channel_width_cm" not in opts:
        raise InputError(field("wall_friction_deg"), f"has no effect without "
                         f"{field('channel_width_cm')} (the side walls it is the friction of)")
    if "channel_width_cm" in opts:
        kw["channel_width"] = opts["channel_width_cm"] * CM
    if "wall_friction_deg" in opts:
        kw["wall_friction"] = math.radians(opts["wall_friction_deg"])
    if "bed_pad_cm" in opts:
        kw["bed_pad"] = opts["bed_pad_cm"] * CM
    if "leg_friction_deg" in opts:
        kw["leg_friction"] = math.radians(opts["leg_friction_deg"])
    try:
        cfg = SPHConfig(dx=dx, **kw)
    except InputError as e:
        f = {"dx": "dx_mm", "settle-time": "settle_time_s", "lowpass": "lowpass_hz",
             "channel-width": "channel_width_cm", "wall-friction": "wall_friction_deg",
             "bed-pad": "bed_pad_cm", "leg-friction": "leg_friction_deg"}.get(
            e.field, e.field.replace("-", "_"))
        raise InputError(field(f), str(e).split(": ", 1)[-1]) from None
    if "backend" in opts:
        resolve_backend(cfg.backend)  # gpu without a GPU: fail before any work
    return cfg


def material(medium, opts: dict, field=lambda k: k.replace("_", "-")):
    """The material: a Li 2013 medium (optionally another friction angle; its shipped
    calibration at the run's particle spacing where there is one), the user's own (density
    and friction angle) or a :class:`terradyn.sph.GranularMaterial` as it is."""
    from .. import media
    from ..sph.materials import GranularMaterial, from_medium, from_properties

    if isinstance(medium, GranularMaterial):
        return medium
    if "density_kg_m3" in opts:
        if "friction_deg" not in opts:
            raise InputError(field("friction_deg"), "your own medium (density) needs a friction angle "
                                                    "(find it: terradyn sph calibrate)")
        if opts.get("dilatancy", "none") != "none":
            raise InputError(field("dilatancy"), "'bolton' needs a Li 2013 medium with both packings "
                                                 "(poppy CP, 0.3 mm glass CP), not your own density")
        if opts.get("rheology", "constant") != "constant":
            raise InputError(field("rheology"), "'mu-i' needs a Li 2013 medium (its grain size and "
                                                "density, Table S1), not your own density")
        if opts.get("calibration_bed", "standard") != "standard":
            raise InputError(field("calibration_bed"), "'large' picks a shipped calibration of a Li "
                                                       "2013 medium; your own medium has its friction_deg")
        return from_properties(medium, opts["density_kg_m3"], opts["friction_deg"],
                               dp_match=opts.get("dp_match") or "plane-strain")
    if medium not in media.MEDIA:
        raise InputError(field("medium"), f"unknown medium {medium!r}; allowed: {', '.join(media.MEDIA)} "
                         "(or give a density and friction angle for your own)")
    try:
        return from_medium(medium, friction_deg=opts.get("friction_deg"),
                           dilatancy=opts.get("dilatancy") or "none",
                           dp_match=opts.get("dp_match") or "plane-strain",
                           rheology=opts.get("rheology") or "constant", dx=_dx(opts),
                           calibration_bed=opts.get("calibration_bed") or "standard")
    except InputError as e:
        if e.field not in ("dilatancy", "dp_match", "calibration_bed"):
            raise
        if e.field in ("dp_match", "calibration_bed"):
            raise InputError(field(e.field), str(e).split(": ", 1)[-1]) from None
        raise InputError(field("dilatancy"), str(e).split(": ", 1)[-1]) from None


def _simulate(body, motion, medium, *, checkpoint=None, progress=None, snapshot_times=(),
              on_run=None, **opts):
    from ..sph.api import simulate_run

    cfg = config(opts)
    mat = material(medium, opts)
    ds, res = simulate_run(body, motion, mat, quick=bool(opts.get("quick", False)), config=cfg,
                           thickness=opts["thickness_cm"] * CM if "thickness_cm" in opts else None,
                           bed_width=opts["bed_width_cm"] * CM if "bed_width_cm" in opts else None,
                           bed_depth=opts["bed_depth_cm"] * CM if "bed_depth_cm" in opts else None,
                           snapshot_times=snapshot_times, checkpoint=checkpoint, progress=progress)
    if on_run is not None:
        on_run(res)
    return ds


def _resolve(opts: dict) -> dict:
    """The sweep form: the solver's defaults filled in, so a case's id names its physics."""
    from ..sph.scenes import LEG_THICKNESS

    medium = opts.pop("medium", None)
    if medium is None:
        raise InputError("model.medium", "missing; name the granular medium")
    field = lambda k: f"model.{k}"  # noqa: E731
    o = MODEL.check_options(opts, field=field)
    material(medium, o, field)
    cfg = config(o, field)
    quick = bool(o.get("quick", False))
    out = {"medium": medium, "quick": quick, "dx_mm": _canon(cfg.dx * 1e3), "hdx": _canon(cfg.hdx),
           "cfl": _canon(cfg.cfl), "av_alpha": _canon(cfg.av_alpha), "av_beta": _canon(cfg.av_beta),
           "wall_layers": int(cfg.wall_layers), "noslip": bool(cfg.noslip), "boundary": cfg.boundary,
           "thickness_cm": _canon(o.get("thickness_cm", LEG_THICKNESS / CM))}
    for k in ("friction_deg", "density_kg_m3", "backend"):
        if k in o:
            out[k] = _canon(o[k]) if isinstance(o[k], float) else o[k]
    if o.get("dilatancy", "none") != "none":  # absent = none: case ids of older stores kept
        out["dilatancy"] = o["dilatancy"]
    if o.get("dp_match", "plane-strain") != "plane-strain":  # absent = the default cone
        out["dp_match"] = o["dp_match"]
    if o.get("rheology", "constant") != "constant":  # absent = rate-independent
        out["rheology"] = o["rheology"]
    if o.get("calibration_bed", "standard") != "standard":  # absent = the standard bed
        out["calibration_bed"] = o["calibration_bed"]
    if cfg.settle_time is not None:
        out["settle_time_s"] = _canon(cfg.settle_time)
    if cfg.lowpass_hz is not None:
        out["lowpass_hz"] = _canon(cfg.lowpass_hz)
    for k in ("bed_width_cm", "bed_depth_cm", "bed_pad_cm", "channel_width_cm", "wall_friction_deg",
              "leg_friction_deg"):
        if k in o:
            out[k] = o[k]
    return out


#: The material values a stored case is compared on before a sweep resumes.
PHYSICS_KEYS = ("density_kg_m3", "youngs_Pa", "friction_deg", "dilatancy_deg", "dp_match")


def physics(params: dict) -> dict:
    """The material a resolved sweep case runs with (defaults filled from the shipped
    calibration): the values of :data:`PHYSICS_KEYS` of ``GranularMaterial.describe()``."""
    opts = {k: v for k, v in params.items() if k not in ("name", "medium")}
    d = material(params["medium"], opts, lambda k: f"model.{k}").describe()
    return {k: d[k] for k in PHYSICS_KEYS}


def _canon(x: float) -> float:
    return float(f"{float(x):.12g}")


MODEL = Model("sph", _simulate, OPTIONS, resolve_fn=_resolve,
              controls=("checkpoint", "progress", "snapshot_times", "on_run"),
              legacy={"boundary": "guard"},  # stores made before the resolved boundary
              physics=physics,
              description="SPH: elasto-plastic (Drucker-Prager) granular bed with the rigid leg in it.")
