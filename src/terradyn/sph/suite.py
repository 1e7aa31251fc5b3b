"""``terradyn sph validate``: the SPH model against measurements, one table of checks.

Each check is a row: quantity, ours, reference, its source, difference, tolerance, pass or
fail. Scenes (issue 17): the bed at rest (analytic), column collapses (Lube et al. 2005),
the plate pushed down in the five media (Li 2013 Table S3: the calibration target), the
virtual plate rig (SPH's own alpha_z, alpha_x maps beside Li 2013 Table S5; only the
plate-down point calibrated the medium, the rest judge it), and the three legs in the two
media with measured curves (Li 2013 Fig. S5, ``terradyn/data/li2013_fig_s5_experiments.csv``)
with RFT (measured grid, linear) as the bar to clear.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from importlib import resources

import numpy as np

from ..errors import InputError, choice, integer
from ..geometry import ArcLeg, make_leg
from ..media import LI2013, MEDIA, stress_model
from ..motion import PlanarMotion, Rotation
from ..units import CM, DEG, N_PER_CM3
from .runstore import RUN_MODULES, code_digest, stored

SCENES = ("bed", "column", "plate", "rig", "legs")
#: Media with measured leg curves (Li 2013 Fig. S5).
LEG_MEDIA = ("poppy LP", "0.3 mm glass CP")
LEGS = ("flat", "c", "reverse-c")
FIG_S5 = "li2013_fig_s5_experiments.csv"
#: The plate of Li 2013's coefficient measurements (chord x width, m) and its thickness.
RIG_PLATE = (3.81 * CM, 2.54 * CM, 0.64 * CM)


@dataclass
class Check:
    scene: str
    quantity: str
    ours: float
    reference: float | None
    source: str
    tolerance: str
    passed: bool | None
    unit: str = ""

    def describe(self) -> dict:
        diff = (None if self.reference in (None, 0) or self.ours is None
                else round(self.ours / self.reference - 1, 4))
        return {"scene": self.scene, "quantity": self.quantity, "ours": _r(self.ours),
                "reference": _r(self.reference), "unit": self.unit, "source": self.source,
                "relative_difference": diff, "tolerance": self.tolerance,
                "verdict": {True: "pass", False: "fail", None: "no published number"}[self.passed]}


def _r(v):  # six significant digits (small numbers keep theirs)
    return None if v is None else (float(f"{float(v):.6g}") if math.isfinite(v) else None)


def measured_legs():
    """Li 2013 Fig. S5 leg curves as a DataFrame (medium, leg, force, theta_deg, force_N)."""
    import pandas as pd

    with resources.files("terradyn.data").joinpath(FIG_S5).open() as f:
        return pd.read_csv(f)


# ----------------------------------------------------------------------------- plate rig
def rig_point(mat, beta: float, gamma: float, *, dx=4e-3, depth=0.03, travel=0.02,
              speed=0.02, config=None, realization: int = 0) -> tuple[float, float]:
    """SPH's alpha_z, alpha_x (N/m^3) of Li 2013's small plate (3.81 cm chord, 2.54 cm wide,
    0.64 cm thick) at attack angle ``beta`` moving in direction ``gamma`` (rad; Li's
    conventions: beta > 0 leading edge up, gamma > 0 downward, alpha_z + up, alpha_x +
    against the motion's horizontal component; the motion is (cos gamma, -sin gamma)). The
    plate starts in the settled bed with its centre ``travel``/2 before ``depth`` along its
    path and moves ``travel`` at ``speed``; alpha = force / (area |z_centre|), averaged over
    the second half of the travel (after the failure has formed). ``realization`` k > 0
    starts the plate k x 10 nm higher (another realization of the chaotic flow, as
    :func:`terradyn.sph.validation.plate_push` does)."""
    from .api import simulate
    from .state import SPHConfig

    L, W, T = RIG_PLATE
    cfg = config or SPHConfig(dx=dx)
    ux, uz = math.cos(gamma), -math.sin(gamma)
    c0 = np.array([-0.5 * travel * ux, -depth - 0.5 * travel * uz + 1e-8 * int(realization)])
    dur = travel / speed
    t = np.linspace(0.0, dur, 41)
    cx = c0[0] + ux * speed * t
    cz = c0[1] + uz * speed * t
    hx = cx - 0.5 * L * math.cos(beta)  # the hip at the plate's trailing end
    hz = cz - 0.5 * L * math.sin(beta)
    mot = PlanarMotion(t, hx, hz, np.full_like(t, -beta), hip_vx=np.full_like(t, ux * speed),
                       hip_vz=np.full_like(t, uz * speed), angular_velocity=np.zeros_like(t))
    plate = ArcLeg(W, 20, L, 0.0, "rig plate", direction=math.pi / 2)
    ds = simulate(plate, mot, mat, config=cfg, thickness=T, bed_width=0.16,
                  bed_depth=depth + 0.5 * travel + 0.05)
    late = t >= 0.5 * dur
    zc = np.abs(cz[late])
    az = float(np.mean(ds.Fz.values[late] / (L * W * zc)))
    ax = float(np.mean(-ds.Fx.values[late] / (L * W * zc)))
    return az, ax


def rig_grid(quick: bool):
    """The (beta, gamma) points of the rig: Table S5's 7 x 13 grid without the beta = -pi/2
    row (the same plate as +pi/2), or a 3 x 5 subset for ``quick``."""
    if quick:
        return (np.array([-np.pi / 4, 0.0, np.pi / 4]),
                np.array([-np.pi / 2, -np.pi / 4, 0.0, np.pi / 4, np.pi / 2]))
    return np.linspace(-np.pi / 3, np.pi / 2, 6), np.linspace(-np.pi / 2, np.pi / 2, 13)


def plate_rig(mat, *, quick=False, dx=4e-3, progress=None, config=None) -> dict:
    """SPH alpha maps of ``mat`` on :func:`rig_grid` with the measured Table S5 values at the
    same points (N/cm^3) and the RMS differences as fractions of the largest measured
    |alpha_z| (the issue-17 target: <= 0.2 each). ``config``: the :class:`SPHConfig` of every
    point (None: the defaults at ``dx``)."""
    betas, gammas = rig_grid(quick)
    B, G = np.meshgrid(betas, gammas, indexing="ij")
    az = np.zeros(B.shape)
    ax = np.zeros(B.shape)
    k = 0
    for i in range(B.shape[0]):
        for j in range(B.shape[1]):
            az[i, j], ax[i, j] = rig_point(mat, B[i, j], G[i, j], dx=dx, config=config)
            k += 1
            if progress:
                progress(k, B.size)
    return rig_against_table(mat.name, betas, gammas, az / N_PER_CM3, ax / N_PER_CM3)


def rig_against_table(medium: str, betas, gammas, az, ax) -> dict:
    """SPH alpha maps ``az``, ``ax`` (N/cm^3, shape (len(betas), len(gammas))) beside Table S5
    of ``medium`` at the same points, with the RMS differences as fractions of the largest
    measured |alpha_z|."""
    B, G = np.meshgrid(betas, gammas, indexing="ij")
    mx, mz = stress_model(medium, "table").alpha(B, G)  # StressModel.alpha returns (alpha_x, alpha_z)
    mz, mx = np.asarray(mz) / N_PER_CM3, np.asarray(mx) / N_PER_CM3
    az, ax = np.asarray(az, float), np.asarray(ax, float)
    scale = float(np.abs(mz).max())
    return {"beta": betas, "gamma": gammas, "alpha_z": az, "alpha_x": ax,
            "alpha_z_measured": mz, "alpha_x_measured": mx,
            "rms_z_frac": float(np.sqrt(np.mean((az - mz) ** 2)) / scale),
            "rms_x_frac": float(np.sqrt(np.mean((ax - mx) ** 2)) / scale)}


def rig_table(rig: dict, name: str = "SPH rig", method: str = "linear"):
    """The rig's own alpha maps (a :func:`rig_against_table` / ``benchmarks/sph_rig.py``
    result on the full grid: ``beta``, ``gamma`` in rad, ``alpha_z``, ``alpha_x`` in N/cm^3)
    as a :class:`terradyn.media.StressTable`, so that RFT can be built from SPH's local
    stresses: RFT from this table against the SPH legs separates what the SPH leg owes to
    its local stresses from what it owes to the scene (history, the leg's own wake). The
    grid's missing beta = -pi/2 row is the beta = +pi/2 plate (the same vertical plate; Table
    S5 lists it twice with equal values)."""
    from ..media import StressTable

    b = np.asarray(rig["beta"], float)
    g = np.asarray(rig["gamma"], float)
    az = np.asarray(rig["alpha_z"], float) * N_PER_CM3
    ax = np.asarray(rig["alpha_x"], float) * N_PER_CM3
    if az.shape != (len(b), len(g)) or ax.shape != az.shape:
        raise InputError("rig", f"alpha maps of shape {az.shape} do not match the grid "
                                f"({len(b)} beta x {len(g)} gamma)")
    if not (abs(b[-1] - np.pi / 2) < 1e-6 and abs(g[0] + np.pi / 2) < 1e-6
            and abs(g[-1] - np.pi / 2) < 1e-6) or b[0] <= -np.pi / 2 + 1e-6:
        raise InputError("rig", "needs the full rig grid: beta up to pi/2 (without -pi/2), "
                                "gamma from -pi/2 to pi/2 (benchmarks/sph_rig.py without --quick)")
    B = np.concatenate([[-np.pi / 2], b])
    B[-1] = np.pi / 2
    G = g.copy()
    G[0], G[-1] = -np.pi / 2, np.pi / 2
    return StressTable(name, B, G, np.vstack([az[-1:], az]), np.vstack([ax[-1:], ax]), method,
                       "SPH virtual plate rig (terradyn.sph.suite.rig_point)")


def measured_grid_rft(medium: str, leg: str = "flat", omega: float = 1.1, hip_height: float = 2 * CM):
    """RFT on Li 2013's measured grid (Table S5, linear) for the rotating-leg test of ``leg``
    (flat, c or reverse-c; -135..135 deg, 271 angles): the sum of the medium's measured local
    plate stresses along the leg, the baseline the leg scores compare with."""
    from ..rft import simulate as rft_simulate

    return rft_simulate(make_leg(leg), Rotation(omega=omega, hip_height=hip_height,
                                                theta_start=-135 * DEG, theta_end=135 * DEG,
                                                n_theta=271),
                        stress_model(medium, "table", interp="linear"))


def leg_scores(medium: str, theta_deg, fz, fx, omega: float = 1.1, leg: str = "flat") -> dict:
    """A leg's curve (e.g. :func:`terradyn.sph.plate3d.leg3d`'s) against Li 2013 Fig. S5's
    measured one for that leg (flat, c or reverse-c), as :func:`leg_vs_measured` scores the
    2D leg: measured peaks and the RMS differences over the measured angles (N), with RFT's
    (Table S5 grid, linear) beside them. Empty for a medium or leg without measured curves."""
    exp = measured_legs()
    e = exp[(exp.medium == medium) & (exp.leg == leg)]
    if not len(e):
        return {}
    rft = measured_grid_rft(medium, leg, omega)
    out = {}
    for comp, name, curve in (("Fz", "lift", fz), ("Fx", "thrust", fx)):
        q = e[e.force == comp]
        th, y = q.theta_deg.values, q.force_N.values
        ours = np.interp(th, np.asarray(theta_deg, float), np.asarray(curve, float))
        r = np.interp(th, rft.theta.values, rft[comp].values)
        out[f"measured_peak_{name}_N"] = float(y.max())
        out[f"rms_{name}_N"] = round(float(np.sqrt(np.mean((ours - y) ** 2))), 4)
        out[f"rms_{name}_rft_N"] = round(float(np.sqrt(np.mean((r - y) ** 2))), 4)
    return out


# ---------------------------------------------------------------------------------- legs
#: The most runs one leg test may average (``realizations``).
MAX_REALIZATIONS = 20


def check_realizations(n) -> int:
    """``realizations`` as an int in 1..MAX_REALIZATIONS (else a one-line :class:`InputError`)."""
    k = integer("realizations", n, 1)
    if k > MAX_REALIZATIONS:
        raise InputError("realizations", f"must be in 1..{MAX_REALIZATIONS} runs per leg test, got {n}")
    return k


def leg_run_code() -> str:
    """Digest of the sources of :data:`terradyn.sph.runstore.RUN_MODULES` (part of a stored
    leg run's key)."""
    return code_digest(RUN_MODULES)


def leg_run(name: str, motion: Rotation, mat, config, *, store=None, progress=None):
    """One SPH run of the leg ``name`` (flat, c or reverse-c) with ``motion`` in the material
    ``mat`` (a :class:`~terradyn.sph.materials.GranularMaterial`): its force series.

    ``store``: a directory, or None. With a directory a finished run is kept there
    (``leg-NAME-KEY.nc``, KEY a hash of everything that defines the run: leg, motion,
    material, numerical settings and the code, :func:`leg_run_code`) and a later call with the same
    inputs reads it instead of running again; while it runs, a checkpoint beside it
    (``.leg-NAME-KEY.ckpt.npz``, every minute) lets an interrupted run resume where it stopped.
    A file under that name that is not this run's is refused (:class:`InputError` on
    ``store``), never overwritten. Returns (series, True if it was read from the store)."""
    from dataclasses import asdict

    from .api import simulate

    leg = make_leg(name)
    if store is None:
        return simulate(leg, motion, mat, config=config, progress=progress), False
    spec = {"leg": name, "motion": asdict(motion), "material": mat.describe(),
            "config": config.run_items(), "code": leg_run_code()}
    return stored(store, f"leg-{name}", spec,
                  lambda ckpt: simulate(leg, motion, mat, config=config, progress=progress, checkpoint=ckpt))


def leg_vs_measured(name: str, medium, *, omega=1.1, dx=4e-3, config=None, progress=None, realizations: int = 1,
                    store=None):
    """One leg in the rotating-leg test (hip 2 cm, -135..135 deg) in SPH, with RFT (the
    medium's measured grid, linear) and Li 2013 Fig. S5's measured curve: peaks (N) and RMS
    differences from the measurement over the measured angles (N).

    ``realizations`` k > 1 runs the leg k times, run j with the hip j x 10 nm higher (a
    physically nil change that gives another realization of the chaotic granular flow, as in
    the plate test); the SPH curve is then the mean of the runs (the measured curves are means
    over trials, so the peak of the mean curve is what compares), and ``peaks_runs`` and
    ``peak_sem`` give each run's peak and the standard error of the mean curve's peak from the
    runs' scatter. ``store``: a directory where each finished run is kept and from which a
    rerun reads it (:func:`leg_run`): an interrupted study loses at most the run in progress,
    and that one resumes from its checkpoint; ``stored`` in the result counts the runs read."""
    from .materials import from_medium, material
    from .state import SPHConfig

    cfg = config or SPHConfig(dx=dx)
    # a medium by name: its calibration at this particle spacing where one is shipped
    mat = from_medium(medium, dx=cfg.dx) if isinstance(medium, str) and medium in MEDIA else material(medium)
    exp = measured_legs()
    n_real = check_realizations(realizations)

    def motion(j=0):
        return Rotation(omega=omega, hip_height=2 * CM + 1e-8 * j, theta_start=-135 * DEG,
                        theta_end=135 * DEG, n_theta=271)

    got = [leg_run(name, motion(j), mat, cfg, store=store, progress=progress) for j in range(n_real)]
    runs = [r for r, _ in got]
    sph = runs[0].copy()
    for comp in ("Fx", "Fz", "torque"):
        if comp in sph:
            sph[comp] = (sph[comp].dims, np.mean([r[comp].values for r in runs], axis=0))
    if n_real > 1:
        sph.attrs["realizations"] = n_real
    rft = measured_grid_rft(mat.name, name, omega)
    out = {"sph": sph, "rft": rft, "realizations": n_real, "stored": sum(k for _, k in got)}
    for comp in ("Fx", "Fz"):
        e = exp[(exp.medium == mat.name) & (exp.leg == name) & (exp.force == comp)]
        th, y = e.theta_deg.values, e.force_N.values
        s = np.interp(th, sph.theta.values, sph[comp].values)
        r = np.interp(th, rft.theta.values, rft[comp].values)
        peaks = [float(x[comp].values.max()) for x in runs]
        out[comp] = {"peak_sph": float(sph[comp].values.max()), "peak_measured": float(y.max()),
                     "peak_rft": float(rft[comp].values.max()),
                     "rms_sph": float(np.sqrt(np.mean((s - y) ** 2))),
                     "rms_rft": float(np.sqrt(np.mean((r - y) ** 2))),
                     "peaks_runs": peaks,
                     "peak_sem": float(np.std(peaks, ddof=1) / np.sqrt(n_real)) if n_real > 1 else float("nan"),
                     "theta": th, "measured": y}
    return out


# ------------------------------------------------------------------------------- the run
def check_media(scenes=SCENES, media=None, calibration_bed: str = "standard") -> list[str]:
    """The media of a :func:`validate` run (``media``, None: the five), each checked, and
    :class:`InputError` on ``calibration_bed`` unless every medium the scenes use (with the
    columns' 3 mm glass CP) has that shipped calibration: :func:`validate` runs this before
    any scene, and the CLI before it makes its folder."""
    from .calibration import CALIBRATION_BEDS
    from .materials import MATERIALS, from_medium

    media = list(media) if media else list(MATERIALS)
    for m in media:
        choice("medium", m, list(MATERIALS))
    choice("calibration_bed", calibration_bed, list(CALIBRATION_BEDS))
    if calibration_bed != "standard":
        for m in sorted(set(media) | ({"3 mm glass CP"} if "column" in scenes else set())):
            from_medium(m, calibration_bed=calibration_bed)
    return media


def validate(*, quick=False, scenes=SCENES, media=None, dx=None, omega=1.1, progress=None,
             figures_dir=None, realizations: int | None = None, rheology: str = "constant",
             store=None, bed_pad: float | None = None, calibration_bed: str = "standard",
             leg_friction: float | None = None) -> dict:
    """Run the scenes; returns {"checks": [Check.describe()...], "details": {...}}. ``quick``:
    4 mm particles, columns a = 1 only, the rig's 3 x 5 subset, the flat leg only.
    ``realizations``: runs per leg test, averaged (:func:`leg_vs_measured`; None: 3, or 1 when
    ``quick``: the measured curves are trial means, and one run's peaks lie 4-7 % above the
    peak of the mean curve, docs/sph.md "Convergence"). ``rheology``:
    "constant" (rate-independent friction, the model's default) or "mu-i" (Jop et al. 2006's
    mu(I) on top of each medium's calibrated friction angle, :func:`from_medium`) for the
    column, plate, rig and leg scenes. ``store``: a directory for the leg runs
    (:func:`leg_run`): a rerun reads the finished ones and resumes the one it was in.
    ``bed_pad``: the leg scenes' bed beyond the leg's path (m; None: the solver's default,
    :class:`SPHConfig`). ``calibration_bed``: "standard" or "large", which shipped
    calibration the media take (:func:`from_medium`); with "large" the plate scene pushes
    each plate in the bed its calibration was made in. ``leg_friction``: the grain-leg
    friction angle (rad; None: a rough, no-slip leg and plate) of the plate, rig and leg
    scenes (:class:`SPHConfig`)."""
    from . import plots, validation
    from .calibration import plate_bed
    from .state import SPHConfig
    from .materials import RHEOLOGIES, from_medium

    choice("rheology", rheology, list(RHEOLOGIES))

    def material(m, at=None):
        # the medium's calibration at the scene's particle spacing where one is shipped
        return from_medium(m, rheology=rheology, dx=dx if at is None else at,
                           calibration_bed=calibration_bed)

    for s in scenes:
        choice("scene", s, list(SCENES))
    realizations = check_realizations((1 if quick else 3) if realizations is None
                                      else realizations)  # before any scene runs
    from .api import FULL_DX

    dx = dx or (4e-3 if quick else FULL_DX)  # full: the production resolution (docs/sph.md, Convergence)

    def config(at, pad=None):
        # None where every setting is the default: the scenes' own default configurations
        if pad is None and leg_friction is None:
            return None
        return SPHConfig(dx=at, bed_pad=pad, leg_friction=leg_friction)

    config(dx)  # a bad leg_friction: refused before any scene
    media = check_media(scenes, media, calibration_bed)  # before any scene
    say = progress or (lambda msg: None)
    checks: list[Check] = []
    details: dict = {}
    fig = (lambda name: None if figures_dir is None else figures_dir / name)
    if "bed" in scenes:
        say("bed at rest")
        r = validation.bed_at_rest("3 mm glass CP", dx=max(dx, 4e-3), depth=0.06 if quick else 0.1)
        checks.append(Check("bed", "d(-sigma_zz)/d(depth) / (rho g)", r["slope"] / r["rho_g"], 1.0,
                            "hydrostatic equilibrium (analytic)", "within 5 %",
                            abs(r["slope"] / r["rho_g"] - 1) <= 0.05))
        if fig("bed.png"):
            plots.bed(r, fig("bed.png"))
    if "column" in scenes:
        # each column twice: in Lube et al.'s channel (side walls 10 cm apart, with friction:
        # their fits' set-up) and in plane strain without walls (the MPM reference's set-up),
        # at the scene's resolution (a column is seconds to a minute even at 2 mm)
        rows, free = [], []
        W = validation.LUBE2005_CHANNEL
        for a in ((1.0,) if quick else (0.5, 1.0, 2.0, 4.0)):
            say(f"column a = {a:g}")
            r = validation.column_collapse(a, material("3 mm glass CP"), base=0.06,
                                           dx=dx, channel_width=W)
            rows.append(r)
            hf = r["height"] / a
            walls = f"side walls {W * 100:g} cm apart, grain-wall friction = phi"
            if a <= 1.0:
                checks.append(Check("column", f"H_f / H_i, a = {a:g} ({walls})", hf, 1.0,
                                    "Lube et al. 2005 (PRE 72:041301): undisturbed top for a < 1.15 "
                                    f"(without walls a deposit no steeper than phi keeps at most {r['height_bound']:.3g})",
                                    ">= 0.95", hf >= 0.95))
            checks.append(Check("column", f"run-out (L_f - L_i)/L_i, a = {a:g} ({walls})", r["runout"],
                                r["runout_lube"],
                                f"Lube et al. 2005 fits (quasi-2D channel, walls {W * 100:g} cm apart)",
                                "within 25 %", abs(r["runout"] / r["runout_lube"] - 1) <= 0.25))
            if r["runout_plane_strain_mpm"] is not None:
                q = validation.column_collapse(a, material("3 mm glass CP"), base=0.06, dx=dx)
                free.append(q)
                ref = q["runout_plane_strain_mpm"]
                checks.append(Check("column", f"run-out (L_f - L_i)/L_i vs plane-strain continuum, a = {a:g} (no walls)",
                                    q["runout"], ref,
                                    "Dunatunga & Kamrin 2015 plane-strain MPM, 2.28 a (no side walls, as this "
                                    "run; quoted second-hand, sph-fidelity-notes sec. 4)",
                                    "within 25 %", abs(q["runout"] / ref - 1) <= 0.25))
        details["column"] = [{k: v for k, v in r.items() if isinstance(v, float)} | {"channel_width_m": W}
                             for r in rows]
        details["column_no_walls"] = [{k: v for k, v in r.items() if isinstance(v, float)} for r in free]
        if fig("columns.png"):
            plots.columns(rows, fig("columns.png"))
    if "plate" in scenes:
        from .calibration import plate_slope

        for m in media:
            say(f"plate pushed down, {m}")
            mat = material(m)
            pad = plate_bed(m, calibration_bed)  # the bed its calibration was made in
            r = plate_slope(mat, dx=dx, config=config(dx, pad))
            meas = MEDIA[m].alpha_z_plate
            checks.append(Check("plate", f"alpha_z(0, pi/2), {m}", r["alpha_z"] / N_PER_CM3,
                                meas / N_PER_CM3, f"{LI2013}, Table S3 (the calibration target)",
                                "within 15 %", abs(r["alpha_z"] / meas - 1) <= 0.15, "N/cm^3"))
            details.setdefault("plate", {})[m] = {"phi_deg": mat.friction / DEG,
                                                  "slope_N_per_cm3": r["slope"] / N_PER_CM3,
                                                  "intercept_Pa": r["intercept_Pa"]}
    if "rig" in scenes:
        for m in media:
            say(f"plate rig, {m}")
            r = plate_rig(material(m, at=max(dx, 4e-3)), quick=quick, dx=max(dx, 4e-3),
                          config=config(max(dx, 4e-3)))
            for comp in ("z", "x"):
                checks.append(Check("rig", f"RMS(alpha_{comp} - Table S5) / max|alpha_z|, {m}",
                                    r[f"rms_{comp}_frac"], None,
                                    f"{LI2013}, Table S5 ({'3 x 5 subset' if quick else 'grid'})",
                                    "<= 0.20", r[f"rms_{comp}_frac"] <= 0.20))
            details.setdefault("rig", {})[m] = {k: (v.tolist() if hasattr(v, "tolist") else v)
                                                for k, v in r.items()}
            if fig(f"rig_{m.replace(' ', '_')}.png"):
                plots.rig_maps(r, fig(f"rig_{m.replace(' ', '_')}.png"),
                               title=f"virtual plate rig, {m} (phi = {material(m, at=max(dx, 4e-3)).friction / DEG:.1f} deg)")
    if "legs" in scenes:
        for m in [x for x in media if x in LEG_MEDIA]:
            for leg in (("flat",) if quick else LEGS):
                say(f"{leg} leg, {m}")
                r = leg_vs_measured(leg, material(m), omega=omega, dx=dx,
                                    config=config(dx, bed_pad),
                                    realizations=realizations, store=store)
                if r["stored"]:
                    say(f"{leg} leg, {m}: {r['stored']} of {r['realizations']} runs read from {store}")
                details.setdefault("legs", {})[f"{leg} leg, {m}"] = {
                    "realizations": r["realizations"],
                    **{f"{c}_peaks_runs_N": r[c]["peaks_runs"] for c in ("Fz", "Fx")},
                    **{f"{c}_peak_sem_N": r[c]["peak_sem"] for c in ("Fz", "Fx") if r["realizations"] > 1}}
                for comp, what in (("Fz", "lift"), ("Fx", "thrust")):
                    c = r[comp]
                    checks.append(Check("legs", f"peak {what}, {leg} leg, {m}", c["peak_sph"],
                                        c["peak_measured"], f"{LI2013}, Fig. S5 (measured)",
                                        "within 15 %",
                                        abs(c["peak_sph"] / c["peak_measured"] - 1) <= 0.15, "N"))
                    checks.append(Check("legs", f"RMS {what} - measured, {leg} leg, {m}",
                                        c["rms_sph"], c["rms_rft"],
                                        "RFT (Table S5 grid, linear) against the same curve",
                                        "<= RFT's", c["rms_sph"] <= c["rms_rft"], "N"))
                if fig(f"leg_{leg}_{m.replace(' ', '_')}.png"):
                    plots.leg_vs_measured(r, fig(f"leg_{leg}_{m.replace(' ', '_')}.png"),
                                          title=f"{leg} leg, {m}, omega = {omega:g} rad/s")
    return {"checks": [c.describe() for c in checks], "details": details,
            "settings": {"quick": quick, "dx_m": dx, "omega_rad_s": omega, "scenes": list(scenes),
                         "leg_realizations": int(realizations),
                         "media": media, "dp_match": sorted({material(m).dp_match for m in media}),
                         "rheology": rheology, "calibration_bed": calibration_bed,
                         **({} if bed_pad is None else {"bed_pad_m": bed_pad}),
                         **({} if leg_friction is None else {"leg_friction_rad": leg_friction})}}


def summary(result: dict) -> dict:
    v = [c["verdict"] for c in result["checks"]]
    return {"pass": v.count("pass"), "fail": v.count("fail"), "total": len(v)}


__all__ = ["validate", "plate_rig", "rig_point", "leg_vs_measured", "leg_run", "measured_legs", "SCENES",
           "summary"]
