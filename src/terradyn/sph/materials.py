"""Granular materials for the SPH model: elastic-perfectly plastic Drucker-Prager.

Every parameter carries its source (``sources``). The Drucker-Prager cone
sqrt(J2) + alpha_phi I1 - k_c = 0 is matched to the Mohr-Coulomb friction angle phi and
cohesion c in plane strain, for the flow the model has (``dp_match``):

* ``"plane-strain"`` (default): the match for non-dilatant plastic flow (psi = 0, the flow of
  these media at their critical state), alpha_phi = sin(phi) / 3, k_c = c cos(phi). With
  psi = 0 the out-of-plane deviator vanishes in plane-strain plastic flow (sigma_yy = the mean
  of the in-plane principal stresses), so sqrt(J2) = tau_max and the cone is the Mohr-Coulomb
  line tau_max = sin(phi) p + c cos(phi) exactly: the model flows at the friction angle it is
  given (tested: simple shear of one particle mobilises phi). This is the plane-strain match
  of the ABAQUS Analysis User's Manual ("Matching Mohr-Coulomb parameters to the
  Drucker-Prager model", plane strain, non-dilatant flow: tan beta = sqrt(3) sin phi in its
  q-p form).
* ``"bui2008"``: Bui, Fukagawa, Sako & Ohno (2008), Int. J. Numer. Anal. Meth. Geomech.
  32:1537, eq. 22, alpha_phi = tan(phi) / sqrt(9 + 12 tan^2 phi), k_c = 3 c / sqrt(9 + 12
  tan^2 phi): the plane-strain match for *associated* flow (psi = phi). Used with the
  non-dilatant flow rule it mobilises only asin(3 alpha_phi): 20.5 deg for 21, 33.8 for 36,
  42.4 for 47 deg. It was the model's match before 2026-12-02 and is kept for comparison.

The dilatancy constant alpha_psi = tan(psi) / sqrt(9 + 12 tan^2 psi) = sin(psi) /
sqrt(9 + 3 sin^2 psi) makes the plastic volume rate per unit in-plane shear rate sin(psi) in
plane strain (the Mohr-Coulomb definition of psi), in both matches.

Bulk densities: Li, Zhang & Goldman (2013) supplement Table S1 (grain density x volume
fraction). Friction angles: for each of the five media, the angle at which the SPH plate test
at the production resolution reproduces the medium's measured plate slope alpha_z(0, pi/2)
(Li 2013 Table S3), shipped in ``terradyn/data/sph_calibration.json`` (``terradyn sph
calibrate``; the plate-down point is the only measurement that sets it, docs/sph.md); without
a calibration, the angle of repose (Table S1) of a cohesionless packing. Poisson's ratio 0.3: Bui et al. (2008). Young's modulus: a
*numerical* stiffness (0.25 MPa). Real packings are stiffer (tens of MPa), but the forces of
slow, plastic flow hardly depend on it while rho g H / E << 1 (here < 0.7 %), and the explicit
time step scales with 1/sqrt(E): 0.25 MPa keeps the sound speed (14 m/s) > 150 x the fastest
leg speed of the thesis's tests (so the flow stays quasi-static) and the full rotating-leg
test inside its time budget. Stiffness check (docs/sph.md): flat leg, intrusion -65..-50 deg
at 2 rad/s, quick resolution: mean lift 3.76 N at 0.25 MPa vs 3.94 N at 1 MPa (-4.5 %),
thrust 1.31 vs 1.36 N (-4 %). With the resolved leg boundary of issue 17 that no longer
holds: the flat leg's peak lift in poppy LP is 5.75 N at 0.25 MPa and 7.12 N at 1 MPa, and the
plate test at high friction angles depends on E strongly (docs/sph.md, "Validation against
measurements"): 0.25 MPa is kept for speed, not because it is converged.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

from ..errors import InputError, choice, in_range, positive
from ..media import LI2013, MEDIA
from ..units import DEG

BUI2008 = ("H. H. Bui, R. Fukagawa, K. Sako, S. Ohno, Lagrangian meshfree particles method (SPH) "
           "for large deformation and failure flows of geomaterial using elastic-plastic soil "
           "constitutive model, Int. J. Numer. Anal. Meth. Geomech. 32:1537-1570 (2008)")
JAKY1944 = "J. Jaky, The coefficient of earth pressure at rest, J. Soc. Hung. Archit. Eng. (1944)"
JOP2006 = ("P. Jop, Y. Forterre, O. Pouliquen, A constitutive law for dense granular flows, Nature "
           "441:727-730 (2006): mu(I) = mu_s + (mu_2 - mu_s) / (1 + I_0 / I), I = gamma_dot d / "
           "sqrt(P / rho_s); glass beads mu_s = tan 20.9 deg, mu_2 = tan 32.76 deg, I_0 = 0.279")
DUNATUNGA2015 = ("S. Dunatunga, K. Kamrin, Continuum modelling and simulation of granular flows "
                 "through their many phases, J. Fluid Mech. 779:483-513 (2015): mu(I) as the "
                 "rate-dependent yield of an elasto-plastic continuum")
#: Jop et al. (2006)'s glass beads: the rise of the friction coefficient from rest to fast
#: flow, mu_2 - mu_s = tan(32.76 deg) - tan(20.9 deg), and the inertial number I_0 of half
#: the rise.
JOP2006_MU_RISE = math.tan(math.radians(32.76)) - math.tan(math.radians(20.9))
JOP2006_I0 = 0.279
#: The rheologies: rate-independent friction (the brief's Drucker-Prager) or mu(I).
RHEOLOGIES = ("constant", "mu-i")


@dataclass(frozen=True)
class GranularMaterial:
    """A dry granular material (SI). density: bulk density kg/m^3; youngs: Pa; poisson;
    friction (phi) and dilatancy (psi, 0 <= psi <= phi) angles in rad; cohesion Pa; k0:
    lateral stress ratio of the geostatic initial state (None: Jaky's 1 - sin phi);
    critical_density: the bulk density (kg/m^3, below ``density``) at which a dilatant
    material stops dilating (its critical-state packing; required when psi > 0); dp_match:
    how the Drucker-Prager constants match phi and c ("plane-strain" or "bui2008", module
    docstring)."""

    name: str
    density: float
    youngs: float
    poisson: float
    friction: float
    cohesion: float = 0.0
    dilatancy: float = 0.0
    k0: float | None = None
    critical_density: float | None = None
    dp_match: str = "plane-strain"
    mu_rise: float = 0.0
    inertial_i0: float = JOP2006_I0
    grain_diameter: float | None = None
    grain_density: float | None = None
    sources: dict = field(default_factory=dict, compare=False)

    def __post_init__(self):
        positive("density", self.density, "kg/m^3")
        positive("youngs", self.youngs, "Pa")
        in_range("poisson", self.poisson, 0.0, 0.499)
        in_range("friction", self.friction, 0.0, 80 * DEG, "rad")
        in_range("cohesion", self.cohesion, 0.0, 1e9, "Pa")
        in_range("dilatancy", self.dilatancy, 0.0, self.friction, "rad")
        if self.dilatancy > 0.0:
            if self.critical_density is None:
                raise InputError("critical_density", "a dilatant material (psi > 0) needs the "
                                 "density of its critical state, where dilation stops (kg/m^3)")
            in_range("critical_density", self.critical_density, 0.5 * self.density,
                     self.density, "kg/m^3")
        if self.k0 is not None:
            in_range("k0", self.k0, 0.0, 1.0)
        choice("dp_match", self.dp_match, list(DP_MATCHES))
        in_range("mu_rise", self.mu_rise, 0.0, 2.0)
        if self.mu_rise > 0.0:
            if self.dp_match != "plane-strain":
                raise InputError("dp_match", "mu(I) (mu_rise > 0) is matched in plane strain only: "
                                 "use dp_match='plane-strain'")
            in_range("inertial_i0", self.inertial_i0, 1e-4, 10.0)
            for name, v, unit in (("grain_diameter", self.grain_diameter, "m"),
                                  ("grain_density", self.grain_density, "kg/m^3")):
                if v is None:
                    raise InputError(name, f"mu(I) (mu_rise > 0) needs the {name.replace('_', ' ')} "
                                     f"({unit}) to form the inertial number")
                positive(name, v, unit)

    @property
    def rate_constants(self) -> dict:
        """The mu(I) constants of the stress update, by the names the kernels take them
        (:class:`terradyn.sph.physics.StrainPar`): mu_s = tan(phi), mu_rise, mu_i0 = I_0,
        mu_dscale = d sqrt(rho_s) (class docstring); mu_rise = 0: rate-independent."""
        on = self.mu_rise > 0.0
        return {"mu_s": math.tan(self.friction), "mu_rise": float(self.mu_rise) if on else 0.0,
                "mu_i0": float(self.inertial_i0) if on else 1.0,
                "mu_dscale": (float(self.grain_diameter) * math.sqrt(float(self.grain_density))
                              if on else 0.0)}

    @property
    def shear_modulus(self) -> float:
        return self.youngs / (2 * (1 + self.poisson))

    @property
    def bulk_modulus(self) -> float:
        return self.youngs / (3 * (1 - 2 * self.poisson))

    @property
    def sound_speed(self) -> float:
        """P-wave speed sqrt((K + 4G/3)/rho), m/s: sets the explicit time step."""
        return math.sqrt((self.bulk_modulus + 4 * self.shear_modulus / 3) / self.density)

    @property
    def alpha_phi(self) -> float:
        """Friction constant of the cone (module docstring: the match ``dp_match``)."""
        if self.dp_match == "plane-strain":
            return math.sin(self.friction) / 3.0
        t = math.tan(self.friction)
        return t / math.sqrt(9 + 12 * t * t)

    @property
    def alpha_psi(self) -> float:
        """The dilatancy constant of the plastic potential g = sqrt(J2) + alpha_psi I1 (the
        plane-strain match of :attr:`alpha_phi` with psi for phi)."""
        t = math.tan(self.dilatancy)
        return t / math.sqrt(9 + 12 * t * t)

    @property
    def dilation_limit(self) -> float:
        """Density below which the flow is non-dilatant (kg/m^3; 0 when psi = 0)."""
        return float(self.critical_density) if self.dilatancy > 0.0 else 0.0

    @property
    def k_c(self) -> float:
        """Cohesion constant of the cone, Pa (the match ``dp_match``)."""
        if self.dp_match == "plane-strain":
            return self.cohesion * math.cos(self.friction)
        t = math.tan(self.friction)
        return 3 * self.cohesion / math.sqrt(9 + 12 * t * t)

    @property
    def mobilised_friction(self) -> float:
        """The friction angle (rad) the model mobilises in non-dilatant plane-strain plastic
        flow, asin(3 alpha_phi): ``friction`` itself with the default match."""
        return math.asin(min(1.0, 3.0 * self.alpha_phi))

    @property
    def lateral_ratio(self) -> float:
        return self.k0 if self.k0 is not None else 1 - math.sin(self.friction)

    def with_(self, **kw) -> "GranularMaterial":
        return replace(self, **kw)

    def describe(self) -> dict:
        return {"name": self.name, "density_kg_m3": self.density, "youngs_Pa": self.youngs,
                "poisson": self.poisson, "friction_deg": self.friction / DEG,
                "cohesion_Pa": self.cohesion, "dilatancy_deg": self.dilatancy / DEG,
                "critical_density_kg_m3": self.critical_density,
                "k0": self.lateral_ratio, "dp_match": self.dp_match,
                # only with mu(I): the description of a rate-independent material (and so the
                # run keys of its checkpoints) stays what it was before mu(I) existed
                **({"rheology": "mu-i", "mu_rise": self.mu_rise, "inertial_i0": self.inertial_i0,
                    "grain_diameter_m": self.grain_diameter,
                    "grain_density_kg_m3": self.grain_density} if self.mu_rise > 0 else {}),
                "mobilised_friction_deg": self.mobilised_friction / DEG, "sources": self.sources}


NUMERICAL_E = 2.5e5

#: The Drucker-Prager matches to Mohr-Coulomb (module docstring), with their sources.
DP_MATCHES = {
    "plane-strain": ("plane-strain match for non-dilatant flow: alpha_phi = sin(phi) / 3, "
                     "k_c = c cos(phi) (ABAQUS Analysis User's Manual, 'Matching Mohr-Coulomb "
                     "parameters to the Drucker-Prager model', plane strain, psi = 0)"),
    "bui2008": f"plane-strain match for associated flow, {BUI2008}, eq. 22",
}


BOLTON1986 = ("M. D. Bolton, The strength and dilatancy of sands, Geotechnique 36:65-78 (1986): "
              "plane strain phi_max - phi_crit = 0.8 psi_max")


def from_medium(medium: str, youngs: float | None = None, poisson: float = 0.3,
                friction_deg: float | None = None, friction: str | None = None,
                dilatancy: str = "none", dp_match: str = "plane-strain",
                rheology: str = "constant", dx: float | None = None,
                calibration_bed: str = "standard") -> GranularMaterial:
    """The SPH material for a medium of :data:`terradyn.media.MEDIA` (Li 2013 Table S1).

    ``friction``: "repose" (the angle of repose, Table S1) or "calibrated" (the plane-strain
    friction angle at which the SPH plate test reproduces the medium's measured
    alpha_z(0, pi/2), Li 2013 Table S3, from ``terradyn/data/sph_calibration.json``, written
    by ``terradyn sph calibrate``, with the stiffness it was calibrated at; see
    :mod:`terradyn.sph.calibration` and docs/sph.md). Default (None): "calibrated" where the
    package ships a calibration of the medium made with the same ``dp_match`` and
    non-dilatant flow, else "repose"; ``sources["friction"]`` says which.
    ``friction_deg`` overrides both. ``youngs`` (Pa): default the stiffness the calibration
    was made at (calibrated friction) or :data:`NUMERICAL_E`; a given value is used as given.

    ``dilatancy``: "none" (default; psi = 0) or "bolton": a closely packed medium whose loose
    packing Li 2013 also measured (poppy CP, 0.3 mm glass CP) takes the loose packing as its
    critical state: phi = the loose packing's angle, psi = (phi_CP - phi_LP) / 0.8 (Bolton
    1986, plane strain), and dilation stops at the loose packing's bulk density. A loose
    packing is at its critical state (psi = 0).

    ``dp_match``: "plane-strain" (default) or "bui2008", how the cone's constants match phi
    (module docstring).

    ``rheology``: "constant" (default; rate-independent friction) or "mu-i": Jop et al.
    (2006)'s mu(I) with their glass beads' rise mu_2 - mu_s and I_0 (the only measured mu(I)
    in the brief's sources; used for the seeds too, an assumption) on top of the friction
    angle above (which stays the quasi-static one: the plate calibration is unchanged), and
    the medium's grain diameter and grain density from Li 2013 Table S1.

    ``dx`` (m): the particle spacing the material will run at. Where the package ships a
    calibration of the medium made at that spacing, the calibrated friction angle is that
    one (the plate test is not converged in resolution, docs/sph.md "Convergence"); else,
    and when None, the production calibration (2.5 mm), and ``sources["friction"]`` says
    that the run's spacing differs from the calibration's.

    ``calibration_bed``: "standard" (default: the calibration made in the plate test's
    standard bed, 9.5 cm beside the plate, which holds the plate up by 1-13 %) or "large"
    (the calibration made with the plate in a bed past about 0.7 of its Prandtl reach, where
    its slope has settled: 0.3-2.7 deg steeper; production spacing only; docs/sph.md "Bed
    size"). "large" takes the calibrated friction angle, so it cannot go with
    ``friction_deg``, ``friction="repose"`` or ``dilatancy="bolton"``."""
    from .calibration import CALIBRATION_BEDS, calibrated_spacings, shipped_at

    choice("dp_match", dp_match, list(DP_MATCHES))
    choice("medium", medium, list(MEDIA))
    choice("dilatancy", dilatancy, ["bolton", "none"])
    choice("rheology", rheology, list(RHEOLOGIES))
    choice("calibration_bed", calibration_bed, list(CALIBRATION_BEDS))
    m = MEDIA[medium]
    large = calibration_bed == "large"
    if large and (friction_deg is not None or friction == "repose" or dilatancy != "none"):
        what = ("a friction angle of your own" if friction_deg is not None
                else "the angle of repose" if friction == "repose" else "Bolton's dilatancy")
        raise InputError("calibration_bed", f"'large' sets the friction angle from the large-bed plate "
                         f"calibration; it cannot go with {what} (drop one)")
    found = shipped_at(medium, dx, bed=calibration_bed)
    if found is not None and found.get("dp_match", "bui2008") != dp_match:
        found = None  # made for the other cone: not a calibration of this model
    if large and found is None:
        raise InputError("calibration_bed", f"no large-bed plate calibration of {medium!r} is shipped "
                         f"(Drucker-Prager match {dp_match!r}); use 'standard'")
    if friction is None:
        friction = ("calibrated" if found is not None and friction_deg is None
                    and dilatancy == "none" else "repose")
    choice("friction", friction, ["calibrated", "repose"])
    cal = found if friction == "calibrated" else None
    if friction == "calibrated" and cal is None and friction_deg is None:
        raise InputError("friction", f"no shipped plate-test calibration for {medium!r} "
                                     f"(Drucker-Prager match {dp_match!r}): run "
                                     "'terradyn sph calibrate' and pass its friction_deg")
    if friction_deg is not None:
        phi = in_range("friction", friction_deg, 0, 80, "deg") * DEG
        src = "user"
    elif cal is not None:
        phi = cal["friction_deg"] * DEG
        e_cal = cal.get("youngs_Pa", NUMERICAL_E)  # the stiffness it was calibrated with
        youngs = e_cal if youngs is None else youngs
        bed = cal.get("plate_test", {}).get("bed_pad_m")
        src = (f"calibrated: the SPH plate test (dx = {cal['dx_m'] * 1e3:g} mm, E = "
               f"{e_cal / 1e6:g} MPa, {dp_match} match"
               + ("" if bed is None else f", plate bed {bed * 100:g} cm beside and below it")
               + (f", mean of {cal.get('realizations')} runs started at as many lattice phases"
                  if cal.get("starts") == "phase" else "") + ") reproduces the "
               f"measured alpha_z(0, pi/2) = {cal['alpha_z_measured_N_per_cm3']:g} N/cm^3 "
               f"({LI2013}, Table S3) within {abs(cal['relative_difference']) * 100:.1f} %; "
               "terradyn sph calibrate")
        if dx is not None and abs(cal["dx_m"] - dx) > 1e-9:
            at = ([cal["dx_m"] * 1e3] if large else calibrated_spacings(medium))
            src += (f"; this run's dx = {dx * 1e3:g} mm has no calibration of its own (shipped "
                    + ("in the large bed " if large else "") + "at "
                    + ", ".join(f"{v:g}" for v in at)
                    + " mm): its plate slope differs from the measured one (docs/sph.md, Convergence)")
    else:
        phi = m.repose_angle
        src = f"angle of repose, {LI2013}, Table S1"
    youngs = NUMERICAL_E if youngs is None else youngs
    psi, rho_crit, psi_src = 0.0, None, "0: non-dilatant flow (Bui et al. 2008)"
    if dilatancy == "bolton" and medium.endswith(" CP"):
        loose = MEDIA.get(medium[:-3] + " LP")
        if loose is None:
            raise InputError("dilatancy", f"{medium!r} has no loosely packed sibling in Li "
                             "2013 Table S1 to define its critical state: use 'none' (or 'bolton' "
                             "for poppy CP, 0.3 mm glass CP)")
        if friction_deg is not None or friction != "repose":
            raise InputError("dilatancy", "'bolton' sets the friction angle itself (the loose "
                             "packing's); drop friction_deg / friction='calibrated'")
        psi = (m.repose_angle - loose.repose_angle) / 0.8
        phi = loose.repose_angle
        rho_crit = loose.bulk_density
        src = f"the loose packing's angle of repose (its critical state), {LI2013}, Table S1"
        psi_src = f"{BOLTON1986}, with phi_max, phi_crit = Table S1 angles of CP, LP"
    return GranularMaterial(
        name=medium, density=m.bulk_density, youngs=youngs, poisson=poisson, friction=phi,
        dilatancy=psi, critical_density=rho_crit, dp_match=dp_match,
        **(dict(mu_rise=JOP2006_MU_RISE, inertial_i0=JOP2006_I0, grain_diameter=m.grain_diameter,
                grain_density=m.grain_density) if rheology == "mu-i" else {}),
        sources={
            **({"rheology": f"mu(I): rise and I_0 of glass beads, {JOP2006}; elasto-plastic "
                            f"form: {DUNATUNGA2015}; grain size and density: {LI2013}, Table S1"}
               if rheology == "mu-i" else {}),
            "dilatancy": psi_src,
            "density": f"grain density x volume fraction, {LI2013}, Table S1",
            "friction": src,
            "poisson": BUI2008,
            "youngs": "numerical stiffness (see terradyn.sph.materials docstring)",
            "cohesion": "0: dry cohesionless grains",
            "k0": f"Jaky 1 - sin(phi): {JAKY1944}",
            "drucker_prager_constants": DP_MATCHES[dp_match],
        })


#: Material presets by medium name (the five media of Li 2013).
MATERIALS: dict[str, GranularMaterial] = {name: from_medium(name) for name in MEDIA}


def from_properties(name: str, density: float, friction_deg: float, *,
                    youngs: float = NUMERICAL_E, poisson: float = 0.3,
                    cohesion: float = 0.0, dp_match: str = "plane-strain") -> GranularMaterial:
    """A user's medium from its measured properties (SI; friction in deg): bulk density
    (grain density x volume fraction), friction angle (for the SPH's plane-strain model,
    best the angle :func:`terradyn.sph.calibration.calibrate_friction` finds from one plate
    test of the medium)."""
    positive("density", density, "kg/m^3")
    phi = in_range("friction", friction_deg, 0, 80, "deg") * DEG
    return GranularMaterial(name=name, density=density, youngs=youngs, poisson=poisson,
                            friction=phi, cohesion=cohesion, dp_match=dp_match,
                            sources={"density": "user", "friction": "user",
                                     "poisson": BUI2008,
                                     "drucker_prager_constants": DP_MATCHES[dp_match],
                                     "youngs": "numerical stiffness (see terradyn.sph.materials)",
                                     "k0": f"Jaky 1 - sin(phi): {JAKY1944}"})


def material(name_or_material: str | GranularMaterial, dx: float | None = None) -> GranularMaterial:
    """A material as given, or a Li 2013 medium's preset by name; with ``dx`` (m, the particle
    spacing it will run at) the medium's calibration at that spacing where one is shipped
    (:func:`from_medium`)."""
    if isinstance(name_or_material, GranularMaterial):
        return name_or_material
    choice("medium", name_or_material, list(MATERIALS))
    return MATERIALS[name_or_material] if dx is None else from_medium(name_or_material, dx=dx)
