"""The SPH validation scenes of issue 4: each returns plain numbers and arrays (SI) that the
tests check in quick form and :mod:`terradyn.sph.plots` draws in full form.

1. :func:`bed_at_rest`  - stresses with depth against the geostatic values.
2. :func:`column_collapse` - run-out and final height against Lube et al. (2005).
3. :func:`plate_push` - a horizontal plate pushed down: alpha_z(0, pi/2) against Li (2013).
4. :func:`rotating_leg` - SPH against RFT for a leg in the rotating-leg test.
"""
from __future__ import annotations

import math

import numpy as np

from ..errors import in_range, positive
from ..geometry import ArcLeg
from ..media import MEDIA, stress_model
from ..motion import PlanarMotion, Rotation
from ..units import CM, DEG, G, N_PER_CM3
from .materials import GranularMaterial, material as _material
from .scenes import bed_scene, column_scene, slope_scene
from .solver import run
from .state import BED_PAD_RANGE, SPHConfig

LUBE2005 = ("G. Lube, H. E. Huppert, R. S. J. Sparks, A. Freundt, Collapses of two-dimensional "
            "granular columns, Phys. Rev. E 72:041301 (2005)")


# ---------------------------------------------------------------------------- 1. bed at rest
def bed_at_rest(medium="3 mm glass CP", *, width=0.2, depth=0.1, dx=4e-3, initial="zero",
                settle_time: float | None = None, bins: int = 10) -> dict:
    """Settle a bed under gravity (from zero stress by default) and bin the stresses by depth.

    Returns depth (bins,) m, szz, sxx (bins,) Pa (tension positive, so negative), the
    geostatic rho g d, the fitted slope d(-szz)/d(depth) (Pa/m) against rho g, and the lateral
    ratio sxx/szz against the Drucker-Prager limit (1 - sqrt3 a)/(1 + 2 sqrt3 a) that a bed
    loaded from zero stress reaches (its elastic K0 = nu/(1 - nu) lies outside the cone)."""
    cfg = SPHConfig(dx=dx, settle_time=settle_time)
    mat = _material(medium, cfg.dx)
    sc = bed_scene(width=width, depth=depth, medium=mat, initial=initial, config=cfg)
    res = run(sc, 0.0 if initial == "zero" else 0.1)
    s = res.solver
    st = s.stress()
    core = np.abs(st["x"]) < 0.25 * width
    d = -st["z"][core]
    edges = np.linspace(0, depth, bins + 1)
    k = np.clip(np.digitize(d, edges) - 1, 0, bins - 1)
    mid = 0.5 * (edges[1:] + edges[:-1])
    szz = np.array([st["szz"][core][k == b].mean() for b in range(bins)])
    sxx = np.array([st["sxx"][core][k == b].mean() for b in range(bins)])
    inner = (mid > 3 * dx) & (mid < depth - 3 * dx)  # away from the free surface and floor
    slope = float(np.polyfit(mid[inner], -szz[inner], 1)[0])
    a = mat.alpha_phi
    r3 = math.sqrt(3) * a
    return {"depth": mid, "szz": szz, "sxx": sxx, "geostatic": mat.density * G * mid,
            "slope": slope, "rho_g": mat.density * G,
            "lateral_ratio": float(np.median(sxx[inner] / szz[inner])),
            "lateral_ratio_dp_limit": (1 - r3) / (1 + 2 * r3),
            "lateral_ratio_k0": mat.lateral_ratio, "initial": initial,
            "max_speed": float(np.hypot(s.vx[s.sidx], s.vz[s.sidx]).max())}


# ----------------------------------------------------------------------- 2. column collapse
def lube2005(aspect) -> tuple[np.ndarray, np.ndarray]:
    """Lube et al. (2005) 2D fits: normalised run-out (L_f - L_i)/L_i = 1.2 a (a < 1.8),
    1.9 a^(2/3) (a > 2.8), linear interpolation between; final height H_f/L_i = a (a < 1.15),
    a^(2/5) above."""
    a = np.asarray(aspect, float)
    lo, hi = 1.2 * a, 1.9 * a ** (2 / 3)
    w = np.clip((a - 1.8) / (2.8 - 1.8), 0, 1)
    runout = (1 - w) * lo + w * hi
    height = np.where(a < 1.15, a, a ** 0.4)
    return runout, height


#: Run-out (L_f - L_i)/L_i per unit aspect ratio of a plane-strain frictional continuum
#: without side walls at small a: Dunatunga & Kamrin 2015 (J. Fluid Mech. 779:483) MPM, quoted
#: second-hand (shared/spec/sph-fidelity-notes.md section 4): the reference whose assumptions
#: match this model's (2D, no side-wall friction), against Lube et al. 2005's 1.2 a measured
#: in a channel 10 cm wide.
PLANE_STRAIN_MPM_RUNOUT = 2.28

#: Distance between the side walls of Lube et al. 2005's quasi-2D channel (m; quoted
#: second-hand, shared/spec/sph-fidelity-notes.md section 4): the column scene's walls when it
#: is compared with their fits (``column_collapse(..., channel_width=LUBE2005_CHANNEL)``).
LUBE2005_CHANNEL = 0.10


def static_height_bound(aspect: float, friction: float) -> float:
    """Largest final height H_f / H_i a column of aspect a = H_i / L_i can keep if no slope of
    its deposit is steeper than the friction angle (rad). Area is conserved: a deposit that
    keeps the full height (a plateau p plus a flank at phi) has area H_i (p + H_i / (2 tan phi))
    = H_i L_i, which needs p >= 0, i.e. a <= 2 tan phi; beyond that the tallest deposit is the
    triangle of slope phi, of height sqrt(2 tan(phi) H_i L_i). Returns
    min(1, sqrt(2 tan(phi) / a))."""
    return min(1.0, math.sqrt(2.0 * math.tan(friction) / aspect))


def column_collapse(aspect: float, medium="3 mm glass CP", *, base=0.06, dx=4e-3,
                    duration: float | None = None, snapshots: int = 0,
                    channel_width: float | None = None,
                    wall_friction: float | None = None) -> dict:
    """Collapse a 2D column of width ``base`` and height aspect x base against a wall; returns
    the normalised run-out (L_f - L_i)/L_i and final height H_f/L_i with Lube's values.
    ``channel_width`` (m): the side walls of a quasi-2D channel (Lube et al. 2005's are 10 cm
    apart), with Coulomb friction ``wall_friction`` (rad; None: the medium's friction angle);
    None: plane strain without walls."""
    positive("aspect", aspect)
    mat = _material(medium, dx)
    cfg = SPHConfig(dx=dx, settle_time=0.0, channel_width=channel_width,
                    wall_friction=wall_friction)
    sc = column_scene(aspect, base=base, medium=mat, config=cfg)
    base = sc.meta["base_m"]  # snapped to whole particle spacings
    H = aspect * base
    T = duration if duration is not None else 3.0 * math.sqrt(2 * H / G) + 0.25
    times = np.linspace(0, T, snapshots) if snapshots else ()
    res = run(sc, T, snapshot_times=times)
    s = res.solver
    x = s.x[s.sidx]
    z = s.z[s.sidx]
    # front of the continuous deposit: the first gap wider than 2 dx along x (single grains
    # that skid ahead of the deposit are not part of the run-out, as in the experiments)
    xs = np.sort(x)
    gap = np.flatnonzero(np.diff(xs) > 2 * dx)
    front = float(xs[gap[0]] if len(gap) else xs[-1]) + 0.5 * dx
    top = float(z[x < 2 * dx].max()) + 0.5 * dx if (x < 2 * dx).any() else float(z.max() + 0.5 * dx)
    lr, lh = lube2005(aspect)
    return {"aspect": aspect, "base": base, "runout": (front - base) / base, "height": top / base,
            "channel_width": channel_width,
            "runout_lube": float(lr), "height_lube": float(lh),
            "runout_plane_strain_mpm": PLANE_STRAIN_MPM_RUNOUT * aspect if aspect <= 1.0 else None,
            "height_bound": static_height_bound(aspect, mat.friction),
            "deposit_slope_deg": math.degrees(math.atan2(top, front)), "x": x, "z": z,
            "snapshots": res.snapshots, "max_speed": float(np.hypot(s.vx[s.sidx], s.vz[s.sidx]).max()),
            "p95_speed": float(np.quantile(np.hypot(s.vx[s.sidx], s.vz[s.sidx]), 0.95)),
            "duration": T}


def slope_stability(angle: float, medium="3 mm glass CP", *, height=0.06, dx=4e-3,
                    duration=1.5, channel_width: float | None = None) -> dict:
    """A wedge at ``angle`` (rad) left to stand for ``duration`` s: a Coulomb material keeps a
    slope below its friction angle and fails above it (the infinite-slope limit tan(angle) =
    tan(phi)). Returns the drop of the top at the wall (m), the final mean slope of the flank
    (deg, from the top at the wall to the toe), the largest surface displacement measure
    (the largest drop of the surface height over x, m) and the final speeds."""
    mat = _material(medium, dx)
    cfg = SPHConfig(dx=dx, settle_time=0.0, channel_width=channel_width)
    sc = slope_scene(angle, height=height, medium=mat, config=cfg)
    height = sc.meta["height_m"]
    x0 = sc.particles.x[sc.particles.kind == 0]
    z0 = sc.particles.z[sc.particles.kind == 0]
    res = run(sc, float(duration))
    s = res.solver
    x = s.x[s.sidx]
    z = s.z[s.sidx]
    bins = np.arange(0.0, 3.0 * sc.meta["foot_m"] + 2 * dx, 2 * dx)

    def surface(xs, zs):
        i = np.digitize(xs, bins) - 1
        out = np.zeros(len(bins) - 1)
        np.maximum.at(out, np.clip(i, 0, len(out) - 1), zs + 0.5 * dx)
        return out

    before, after = surface(x0, z0), surface(x, z)
    xs = np.sort(x)
    gap = np.flatnonzero(np.diff(xs) > 2 * dx)
    toe = float(xs[gap[0]] if len(gap) else xs[-1]) + 0.5 * dx
    top = float(after[0])
    return {"angle_deg": math.degrees(angle), "friction_deg": math.degrees(mat.friction),
            "top_drop": height - top, "max_surface_drop": float(np.max(before - after)),
            "final_slope_deg": math.degrees(math.atan2(top, toe)), "toe": toe,
            "height": height, "max_speed": float(np.hypot(s.vx[s.sidx], s.vz[s.sidx]).max())}


# ----------------------------------------------------------------------------- 3. plate push
def plate_push(medium="3 mm glass CP", *, length=3.81 * CM, width=2.54 * CM, thickness=0.64 * CM,
               speed=0.01, depth=0.05, dx=2.5e-3, n_samples=51, config: SPHConfig | None = None,
               fit_from=0.01, realization: int = 0, below: float | None = None) -> dict:
    """Push a horizontal plate straight down at ``speed`` (m/s) from the surface to ``depth``;
    vertical stress on the plate per depth = alpha_z(0, pi/2) (N/m^3), fitted on depths >
    ``fit_from``, against the measured value of Li 2013 (Table S1 footnote, via MEDIA).
    ``realization`` k > 0 starts the plate k x 10 nm higher: a physically nil change that
    gives another realization of the run (the granular flow under the plate is chaotic at
    a few particles across it: slopes of single runs scatter by about 10 %, docs/sph.md).
    ``config.bed_pad`` (m): the bed beyond the plate's edges and below its deepest point; None
    keeps the calibration's bed (6 plate lengths wide, at least 15 cm, and 2 plate lengths,
    at least 4 cm, below the plate's deepest point: docs/sph.md, "Bed size"). ``below`` (m;
    None: as ``config.bed_pad``, or the calibration's bed) sets the bed below the plate's
    deepest point on its own, so that the reach beside the plate and below it can be studied
    apart ("Bed size": the lateral reach is what matters most)."""
    from .api import simulate

    positive("speed", speed, "m/s")
    positive("depth", depth, "m")
    cfg = config or SPHConfig(dx=dx)
    mat = _material(medium, cfg.dx)
    plate = ArcLeg(width, 20, length, 0.0, "plate", direction=math.pi / 2)
    z0 = 0.5 * thickness + 0.5 * cfg.dx + 1e-8 * int(realization)
    T = (depth + z0) / speed
    t = np.linspace(0, T, n_samples)
    mot = PlanarMotion(t, np.full_like(t, -length / 2), z0 - speed * t, np.zeros_like(t),
                       hip_vx=np.zeros_like(t), hip_vz=np.full_like(t, -speed),
                       angular_velocity=np.zeros_like(t))
    if cfg.bed_pad is None:
        bw, bd = max(6 * length, 0.15), depth + max(2 * length, 0.04)
    else:
        bw, bd = length + 2 * cfg.bed_pad, depth + cfg.bed_pad
    if below is not None:
        bd = depth + in_range("below", below, *BED_PAD_RANGE, "m")
    ds = simulate(plate, mot, mat, config=cfg, thickness=thickness, bed_width=bw, bed_depth=bd)
    d = -(z0 - speed * t)  # plate centre depth
    stress = ds.Fz.values / (length * width)
    m = d > fit_from
    slope = float(np.polyfit(d[m], stress[m], 1)[0]) if m.sum() >= 2 else float("nan")
    # sigma = alpha |z| through the origin, as RFT applies it (terradyn.sph.calibration)
    alpha0 = float(np.sum(stress[m] * d[m]) / np.sum(d[m] ** 2)) if m.sum() >= 1 else float("nan")
    ax, az = stress_model(mat.name, "fit").alpha(0.0, np.pi / 2) if mat.name in MEDIA else (0.0, np.nan)
    measured = MEDIA[mat.name].alpha_z_plate if mat.name in MEDIA else None
    return {"depth": d, "stress": stress, "alpha_z": slope, "alpha_z_origin": alpha0,
            "alpha_z_measured": measured,
            "alpha_z_fit": float(az), "series": ds, "Fx": ds.Fx.values}


# --------------------------------------------------------------------------- 4. rotating leg
def compare_with_rft(sph, rft) -> dict:
    """Peak differences (%), mean square errors (N^2), suction and asymmetry of two series on
    the same theta grid (SPH first)."""
    from .. import compare

    th = sph.theta.values
    out = {}
    peaks = compare.peak_difference(rft, sph, absolute=True)
    errs = compare.mse(rft, sph)
    for comp in peaks:
        out[f"peak_{comp}_sph"] = peaks[comp]["peak_b"]
        out[f"peak_{comp}_rft"] = peaks[comp]["peak_a"]
        out[f"peak_{comp}_diff_pct"] = float(100 * peaks[comp]["rel_diff"]) if peaks[comp]["peak_a"] else 0.0
        out[f"mse_{comp}"] = errs[comp]
    for name, s in (("sph", sph), ("rft", rft)):
        fz = s.Fz.values
        out[f"lift_intrusion_max_{name}"] = float(fz[th < 0].max()) if (th < 0).any() else 0.0
        out[f"lift_extraction_max_{name}"] = float(fz[th > 0].max()) if (th > 0).any() else 0.0
        out[f"suction_min_{name}"] = float(fz.min())
        out[f"suction_span_deg_{name}"] = float(np.sum(fz < -1e-3 * max(np.abs(fz).max(), 1e-12))
                                                * (abs(th[1] - th[0]) if len(th) > 1 else 0.0))
    return out


def rotating_leg(leg, omega=0.2, medium="3 mm glass CP", *, quick=False, n_theta=271,
                 theta_start=-135 * DEG, theta_end=135 * DEG, config: SPHConfig | None = None,
                 progress=None, checkpoint=None) -> dict:
    """The rotating-leg test (brief 2.2) in SPH and RFT (the medium's Fourier fit); returns
    both series and :func:`compare_with_rft` numbers."""
    from ..rft import simulate as rft_simulate
    from .api import simulate

    mot = Rotation(omega=omega, hip_height=2 * CM, theta_start=theta_start, theta_end=theta_end,
                   n_theta=n_theta)
    sph = simulate(leg, mot, medium, quick=quick, config=config, progress=progress,
                   checkpoint=checkpoint)
    rft = rft_simulate(leg, mot, stress_model(medium if isinstance(medium, str) else medium.name))
    return {"sph": sph, "rft": rft, "metrics": compare_with_rft(sph, rft)}


def alpha_z_plate_measured(medium: str) -> float:
    """Li 2013 measured alpha_z(0, pi/2), N/m^3."""
    return MEDIA[medium].alpha_z_plate


__all__ = ["bed_at_rest", "column_collapse", "slope_stability", "plate_push", "rotating_leg", "compare_with_rft",
           "lube2005", "LUBE2005", "N_PER_CM3"]
