"""Demo uses of the MuJoCo granular terrain: a six-legged robot walking on granular media, and a
single foot pressed into the bed.

* :func:`hexapod_mjcf` writes the MJCF of a small RHex-like robot (the kind Li et al. 2013
  ran on granular media): a box torso and six rigid arc legs (C, flat or reverse C, a closed
  mesh swept from :class:`terradyn.geometry.ArcLeg`), each on a hip hinge about y driven by a
  position servo; alternating tripod gait, every leg turning full circles at a constant rate.
  The dimensions are this project's choice (:data:`HEXAPOD`), not Li 2013's robot's.
* :func:`walk` runs one robot on one medium and returns its speed; :func:`walk_study` runs
  leg shapes x media; :func:`render_frames` renders a run offscreen (``mujoco.Renderer``, EGL
  or OSMesa). The table, figure and GIF are written by ``terradyn mujoco demo``.
* :func:`press_foot` presses a flat box foot into the bed with a slowly ramped load and
  returns its sinkage against the closed-form RFT equilibrium depth.

SI units throughout; the bed's free surface is z = 0.
"""
from __future__ import annotations

import json

import time
import math
from dataclasses import asdict, dataclass

import numpy as np

from ..errors import InputError, choice, in_range, positive
from ..geometry import make_leg
from ..rft3d import Medium3D, medium3d, scaled_alpha
from .mujoco import GranularTerrain, mujoco

ROBOTS = ("hexapod",)
LEG_SHAPES = ("c", "flat", "reverse-c")
#: The demo's media: poppy seeds (loosely packed) and 3 mm glass beads (closely packed), two of
#: Li 2013's media.
DEMO_MEDIA = ("poppy LP", "3 mm glass CP")

#: What the brief says about Li 2013's robot experiments, for the comparison of the ordering.
LI2013_NOTE = (
    "The project brief (shared/spec/system.md) does not describe Li et al. 2013's robot "
    "experiments: it gives no robot speeds and no speed ordering by leg shape, so no published "
    "robot number is compared here. The closest statement it holds is from the rotating-leg "
    "test (section 2.2): the C-shaped leg gets much larger lift than the flat leg, and the "
    "reverse C the smallest lift, with suction in extraction. The ordering of the demo's speeds "
    "is set against that lift ordering (C > flat > reverse C).")


@dataclass(frozen=True)
class Hexapod:
    """Demo robot dimensions (SI). Torso ``torso`` (lx, ly, lz) m and ``torso_mass`` kg;
    legs: chord ``leg_chord`` m, ``leg_width`` m (along y), ``leg_thickness`` m, ``leg_mass``
    kg; hips at x = -hip_spacing, 0, +hip_spacing on both sides; gait ``frequency`` Hz (leg
    turns per second); servo stiffness ``kp`` N m/rad, damping ``kv`` N m s/rad, torque limit
    ``max_torque`` N m; ``timestep`` s."""

    torso: tuple = (0.13, 0.07, 0.02)
    torso_mass: float = 0.25
    leg_chord: float = 0.04
    leg_width: float = 0.01
    leg_thickness: float = 0.003
    leg_mass: float = 0.005
    hip_spacing: float = 0.05
    frequency: float = 2.0
    kp: float = 2.0
    kv: float = 0.02
    max_torque: float = 0.3
    timestep: float = 0.001
    n_along: int = 12


HEXAPOD = Hexapod()
#: The walk samples the torso's height and tilt every SAMPLE_EVERY physics steps.
SAMPLE_EVERY = 10
HIPS = (("fl", 1, 1, 0), ("ml", 0, 1, 1), ("rl", -1, 1, 0),
        ("fr", 1, -1, 1), ("mr", 0, -1, 0), ("rr", -1, -1, 1))  # name, x index, side, tripod


def leg_mesh(shape: str, chord: float, width: float, thickness: float, n_along: int = 12):
    """Closed triangle mesh (vertices (V, 3) m, faces (F, 3)) of an arc leg swept across
    ``width`` (y) with ``thickness`` normal to its centreline; the hip at the origin, the tip
    at z = -chord (the leg of :func:`terradyn.geometry.make_leg` in the x-z plane)."""
    leg = make_leg(shape, length=chord, width=width)
    c = leg.outline(n_along + 1)  # hip to tip, (x, z)
    d = np.gradient(c, axis=0)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    nu = np.column_stack([-d[:, 1], d[:, 0]])
    loop = np.array([(thickness / 2, -width / 2), (thickness / 2, width / 2),
                     (-thickness / 2, width / 2), (-thickness / 2, -width / 2)])
    V = np.concatenate([np.column_stack([c[i, 0] + loop[:, 0] * nu[i, 0], loop[:, 1],
                                         c[i, 1] + loop[:, 0] * nu[i, 1]]) for i in range(len(c))])
    F = []
    for i in range(len(c) - 1):
        a, b = 4 * i, 4 * (i + 1)
        for k in range(4):
            k2 = (k + 1) % 4
            F += [(a + k, a + k2, b + k2), (a + k, b + k2, b + k)]
    last = 4 * (len(c) - 1)
    F += [(0, 2, 1), (0, 3, 2), (last, last + 1, last + 2), (last, last + 2, last + 3)]
    F = np.array(F, np.int64)
    import trimesh

    if trimesh.Trimesh(V, F, process=False).volume < 0:
        F = F[:, ::-1].copy()
    return V, F


def hexapod_mjcf(leg: str = "c", robot: Hexapod = HEXAPOD) -> str:
    """MJCF text of the demo hexapod with ``leg`` legs (c, flat, reverse-c)."""
    choice("leg", leg, LEG_SHAPES)
    V, F = leg_mesh(leg, robot.leg_chord, robot.leg_width, robot.leg_thickness, robot.n_along)
    lx, ly, lz = robot.torso
    hip_z = -lz / 2
    stand = robot.leg_chord + lz / 2 + 0.005
    y_hip = ly / 2 + robot.leg_width / 2 + 0.002
    legs = []
    for name, ix, side, _ in HIPS:
        legs.append(f"""
      <body name="leg_{name}" pos="{ix * robot.hip_spacing:.6g} {side * y_hip:.6g} {hip_z:.6g}">
        <joint name="hip_{name}" type="hinge" axis="0 1 0" damping="0.001"/>
        <inertial pos="0 0 {-robot.leg_chord / 2:.6g}" mass="{robot.leg_mass:.6g}" diaginertia="{robot.leg_mass * robot.leg_chord ** 2 / 12:.4g} {robot.leg_mass * robot.leg_chord ** 2 / 12:.4g} {robot.leg_mass * robot.leg_width ** 2 / 12:.4g}"/>
        <geom name="leg_{name}" type="mesh" mesh="leg" rgba="0.85 0.35 0.1 1" contype="0" conaffinity="0"/>
      </body>""")
    acts = "\n".join(f'    <general name="servo_{n}" joint="hip_{n}" gainprm="{robot.kp:g}" biastype="affine" '
                     f'biasprm="0 {-robot.kp:g} {-robot.kv:g}" forcelimited="true" '
                     f'forcerange="{-robot.max_torque:g} {robot.max_torque:g}"/>' for n, *_ in HIPS)
    vert = " ".join(f"{x:.7g}" for x in V.ravel())
    face = " ".join(str(int(i)) for i in F.ravel())
    return f"""<mujoco model="terradyn-hexapod-{leg}">
  <compiler angle="radian"/>
  <option timestep="{robot.timestep:g}" integrator="implicitfast"/>
  <visual><global offwidth="640" offheight="480"/></visual>
  <asset>
    <mesh name="leg" vertex="{vert}" face="{face}"/>
    <texture name="grain" type="2d" builtin="checker" rgb1="0.82 0.74 0.55" rgb2="0.74 0.66 0.48" width="64" height="64"/>
    <material name="bed" texture="grain" texrepeat="40 40" rgba="1 1 1 0.55"/>
  </asset>
  <worldbody>
    <light pos="0 -0.5 1.5" dir="0 0.3 -1" directional="true"/>
    <geom name="floor" type="plane" size="3 1 0.1" material="bed"/>
    <body name="torso" pos="0 0 {stand:.6g}">
      <freejoint name="root"/>
      <geom name="torso" type="box" size="{lx / 2:g} {ly / 2:g} {lz / 2:g}" mass="{robot.torso_mass:g}" rgba="0.2 0.3 0.6 1"/>{''.join(legs)}
    </body>
  </worldbody>
  <actuator>
{acts}
  </actuator>
</mujoco>
"""


def terrain_bodies() -> tuple[str, ...]:
    """The demo robot's bodies that feel the terrain: the torso (belly) and the six legs."""
    return ("torso",) + tuple(f"leg_{n}" for n, *_ in HIPS)


def build(leg: str = "c", medium: str | Medium3D = "poppy LP", robot: Hexapod = HEXAPOD,
          stick: bool = True, dynamic_lambda: float | None = None):
    """(model, data, terrain) of the demo hexapod on ``medium`` (name or Medium3D);
    ``dynamic_lambda``: dynamic-RFT lambda (None: quasi-static)."""
    model = mujoco.MjModel.from_xml_string(hexapod_mjcf(leg, robot))
    data = mujoco.MjData(model)
    med = medium3d(medium) if isinstance(medium, str) else medium
    terrain = GranularTerrain(model, med, bodies=terrain_bodies(), stick=stick,
                              dynamic_lambda=dynamic_lambda)
    mujoco.mj_forward(model, data)
    return model, data, terrain


def gait_targets(t: float, robot: Hexapod = HEXAPOD) -> np.ndarray:
    """Hip angle targets (rad) at time t: constant rotation 2 pi f t, tripods half a turn
    apart, starting with tripod 0 pointing down."""
    base = 2 * np.pi * robot.frequency * t
    return np.array([base + np.pi * tri for *_, tri in HIPS])


def gait_schedule(t0: float, n: int, dt: float, robot: Hexapod = HEXAPOD) -> np.ndarray:
    """(n, 6) hip targets of :func:`gait_targets` for the n steps from time t0 (the times
    summed step by step like MuJoCo's ``data.time``): the ``ctrl`` schedule of
    :meth:`GranularTerrain.run`, so the compiled loop drives the robot exactly as a per-step
    controller would."""
    t = np.cumsum(np.concatenate([[t0], np.full(n - 1, dt)])) if n > 0 else np.zeros(0)
    tri = np.array([tri for *_, tri in HIPS], float)
    return (2 * np.pi * robot.frequency * t)[:, None] + np.pi * tri[None, :]


@dataclass
class WalkResult:
    leg: str
    medium: str
    speed_m_s: float
    speed_body_lengths_s: float
    stride_m: float
    duration_s: float
    settle_s: float
    mean_torso_height_m: float
    heading_change_deg: float
    max_tilt_deg: float
    steps: int
    wall_s: float
    terrain_s: float

    @property
    def sim_to_wall(self) -> float:
        return self.duration_s / self.wall_s


def walk(leg: str = "c", medium: str = "poppy LP", duration: float = 4.0, settle: float = 1.0,
         robot: Hexapod = HEXAPOD, frames: list | None = None, fps: float = 25.0,
         renderer=None, dynamic_lambda: float | None = None) -> WalkResult:
    """Run the hexapod for ``duration`` s. Speed: the torso CoM's path over ground after
    ``settle`` s, sampled once per stride (so the bobbing within a stride does not count, and
    a robot that veers is measured along its path), divided by the time; the heading change
    and the largest torso tilt (sampled every :data:`SAMPLE_EVERY` steps) are reported too.
    The physics runs in the compiled loop (:meth:`GranularTerrain.run`, the gait as its ctrl
    schedule: the trajectory of a per-step controller). With ``renderer`` (a mujoco.Renderer),
    frames are appended to ``frames`` at ``fps``."""
    duration = positive("duration", duration, "s")
    settle = in_range("settle", settle, 0.0, duration * 0.9, "s")
    model, data, terrain = build(leg, medium, robot, dynamic_lambda=dynamic_lambda)
    dt = model.opt.timestep
    n = int(round(duration / dt))
    n0 = int(round(settle / dt))
    cam = None
    if renderer is not None:
        cam = mujoco.MjvCamera()
        cam.type = mujoco.mjtCamera.mjCAMERA_TRACKING
        cam.trackbodyid = model.body("torso").id
        cam.distance, cam.elevation, cam.azimuth = 0.45, -20.0, 120.0
    every = max(1, int(round(1 / (fps * dt))))
    stride_steps = max(1, int(round(1 / (robot.frequency * dt))))
    track = []  # torso CoM (x, y) once per stride after the settling time
    heights = []
    min_up = 1.0
    t_terrain = 0.0
    # the compiled loop (GranularTerrain.run) runs `block` steps per call, the gait's targets
    # as its ctrl schedule (the same trajectory as a per-step controller); the torso is
    # sampled between calls: height and tilt every SAMPLE_EVERY steps, the path once per stride
    # (after steps n0 + 1 + k stride, frames after steps 1 + k every: one step in, the first
    # call is a single step)
    block = math.gcd(math.gcd(stride_steps, SAMPLE_EVERY), n0)
    if renderer is not None:
        block = math.gcd(block, every)
    tic = time.perf_counter()
    j = 0  # steps done
    while j < n:
        k = 1 if j == 0 else min(block, n - j)
        res = terrain.run(data, k, ctrl=gait_schedule(data.time, k, dt, robot), timing=True)
        t_terrain += float(np.nansum(res["step_times_s"][:, 1]))
        j += k
        if j > n0:
            heights.append(float(data.xipos[1, 2]))
            min_up = min(min_up, float(data.xmat[1, 8]))
            if (j - 1 - n0) % stride_steps == 0:
                track.append((data.xipos[1, 0], data.xipos[1, 1], math.atan2(data.xmat[1, 3], data.xmat[1, 0])))
        if renderer is not None and (j - 1) % every == 0:
            renderer.update_scene(data, camera=cam)
            frames.append(renderer.render().copy())
    wall = time.perf_counter() - tic
    if not np.isfinite(data.qpos).all():
        raise RuntimeError(f"the {leg} hexapod on {medium} diverged (non-finite state)")
    tr = np.array(track)
    span = (len(tr) - 1) * stride_steps * dt
    path = float(np.linalg.norm(np.diff(tr[:, :2], axis=0), axis=1).sum()) if len(tr) > 1 else 0.0
    v = path / span if span > 0 else float("nan")
    turn = float(np.degrees(np.unwrap(tr[:, 2])[-1] - tr[0, 2])) if len(tr) > 1 else 0.0
    return WalkResult(leg, medium if isinstance(medium, str) else medium.name, v,
                      v / robot.torso[0], v / robot.frequency, duration, settle,
                      float(np.mean(heights)), turn, float(np.degrees(math.acos(min(1.0, max(-1.0, min_up))))),
                      n, wall, t_terrain)


def walk_study(legs=LEG_SHAPES, media=DEMO_MEDIA, duration: float = 4.0, settle: float = 1.0,
               robot: Hexapod = HEXAPOD, progress=None,
               dynamic_lambda: float | None = None) -> list[WalkResult]:
    """Speed of the hexapod for each leg shape on each medium."""
    for leg in legs:
        choice("leg", leg, LEG_SHAPES)
    from ..media import MEDIA

    for m in media:
        choice("medium", m, list(MEDIA))
    out = []
    for m in media:
        for leg in legs:
            r = walk(leg, m, duration, settle, robot, dynamic_lambda=dynamic_lambda)
            if progress:
                progress(f"{leg:9s} on {m:14s}: {r.speed_m_s * 100:6.2f} cm/s "
                         f"({r.sim_to_wall:.1f}x real time)")
            out.append(r)
    return out


def study_table(results: list[WalkResult]) -> list[dict]:
    return [{**asdict(r), "sim_to_wall": r.sim_to_wall} for r in results]


def render_frames(leg: str = "c", medium: str = "poppy LP", duration: float = 3.0,
                  robot: Hexapod = HEXAPOD, width: int = 320, height: int = 240, fps: float = 20.0,
                  dynamic_lambda: float | None = None):
    """Render a walk offscreen (``mujoco.Renderer``; GL backend from ``MUJOCO_GL``, egl by
    default here). Returns (frames, message): a list of (height, width, 3) uint8 RGB arrays,
    or (None, the reason it could not render) - never raises for a missing GL stack."""
    try:
        model = mujoco.MjModel.from_xml_string(hexapod_mjcf(leg, robot))
        renderer = mujoco.Renderer(model, height, width)
    except Exception as e:  # noqa: BLE001 - any GL failure means: no rendering here
        import os

        return None, (f"offscreen rendering is not available (MUJOCO_GL={os.environ.get('MUJOCO_GL')!r}: "
                      f"{type(e).__name__}: {e}); install EGL (libegl1, libegl-mesa0, libgl1-mesa-dri) "
                      f"or OSMesa (libosmesa6) and set MUJOCO_GL=egl or osmesa")
    frames: list = []
    try:
        walk(leg, medium, duration, min(0.5, duration / 2), robot, frames, fps, renderer, dynamic_lambda)
    finally:
        renderer.close()
    return frames, f"{len(frames)} frames, {width}x{height}, {fps:g} fps"


# ------------------------------------------------------------------------------------------
# A single foot pressed into the bed
# ------------------------------------------------------------------------------------------
def foot_mjcf(lx: float, ly: float, lz: float, mass: float, timestep: float = 0.001) -> str:
    return f"""<mujoco model="terradyn-foot">
  <option timestep="{timestep:g}"/>
  <worldbody>
    <geom name="floor" type="plane" size="1 1 0.1"/>
    <body name="foot" pos="0 0 {lz / 2 + 1e-4:g}">
      <freejoint/>
      <geom name="sole" type="box" size="{lx / 2:g} {ly / 2:g} {lz / 2:g}" mass="{mass:g}"/>
    </body>
  </worldbody>
</mujoco>"""


def box_equilibrium_depth(lx: float, ly: float, lz: float, load: float, medium: Medium3D) -> float:
    """Closed-form 3D-RFT depth (m) of the bottom of a level box foot pushed straight down by
    ``load`` N (weight included), when it is buried (depth >= lz): the bottom face feels
    a_b d lx ly, the four sides (their normal horizontal, the motion down) a_s lz (d - lz/2)
    per unit length of the perimeter; a_b, a_s = vertical 3D-RFT stress per depth (N/m^3)."""
    down = np.array([0.0, 0.0, -1.0])
    a_b = scaled_alpha(down, down, medium)[2]
    a_x = scaled_alpha(np.array([1.0, 0, 0]), down, medium)[2]
    a_y = scaled_alpha(np.array([0, 1.0, 0]), down, medium)[2]
    side = 2 * ly * lz * a_x + 2 * lx * lz * a_y  # per m of depth of the sides' centre
    d = (load + side * lz / 2) / (a_b * lx * ly + side)
    if d < lz:
        raise InputError("load", f"too small for the buried-box closed form: depth {d:.3g} m < thickness {lz:g} m")
    return float(d)


def press_foot(medium: str | Medium3D = "3 mm glass CP", load: float = 20.0,
               size=(0.06, 0.04, 0.004), mass: float = 0.2, ramp: float = 1.0,
               hold: float = 0.5, timestep: float = 0.001, stick: bool = True) -> dict:
    """A level box foot (``size`` lx, ly, lz m; ``mass`` kg) pressed into the bed by its
    weight plus a vertical ``load`` N (>= 0), the total ramped up from 0 over ``ramp`` s and
    held for ``hold`` s. Returns the time series (time s, depth m of the foot's bottom, total
    vertical load N) and the final depth against :func:`box_equilibrium_depth` for load +
    weight."""
    med = medium3d(medium) if isinstance(medium, str) else medium
    if in_range("load", load, 0.0, 1e6, "N") == 0 and mass <= 0:
        raise InputError("mass", "must be > 0 kg")
    lx, ly, lz = (positive(k, v, "m") for k, v in zip(("lx", "ly", "lz"), size))
    model = mujoco.MjModel.from_xml_string(foot_mjcf(lx, ly, lz, positive("mass", mass, "kg"), timestep))
    data = mujoco.MjData(model)
    terrain = GranularTerrain(model, med, bodies=("foot",), stick=stick)
    mujoco.mj_forward(model, data)
    n = int(round((ramp + hold) / timestep))
    t, depth, applied = np.empty(n), np.empty(n), np.empty(n)
    weight = mass * -model.opt.gravity[2]
    for i in range(n):
        r = min(1.0, data.time / ramp) if ramp > 0 else 1.0
        # the whole vertical load (weight + load) rises from 0: a lift (1 - r) m g holds the
        # weight back at first, so the sinkage is quasi-static, not a drop
        data.xfrc_applied[1, 2] = -load * r + weight * (1 - r)
        terrain.step(data)
        t[i], depth[i], applied[i] = data.time, -(data.qpos[2] - lz / 2), (load + weight) * r
    try:
        expected = box_equilibrium_depth(lx, ly, lz, load + weight, med)
    except InputError:  # not buried: the closed form does not apply
        expected = None
    return {"time_s": t, "depth_m": depth, "load_N": applied, "final_depth_m": float(depth[-1]),
            "expected_depth_m": expected, "weight_N": float(weight),
            "relative_error": None if expected is None else float(depth[-1] / expected - 1),
            "elements": terrain.n_elements}


def study_json(results: list[WalkResult], extra: dict) -> str:
    return json.dumps({"runs": study_table(results), **extra}, indent=1) + "\n"


__all__ = ["ROBOTS", "LEG_SHAPES", "DEMO_MEDIA", "Hexapod", "HEXAPOD", "hexapod_mjcf", "leg_mesh",
           "build", "walk", "walk_study", "gait_schedule", "SAMPLE_EVERY", "render_frames", "press_foot",
           "box_equilibrium_depth", "foot_mjcf", "terrain_bodies", "gait_targets", "WalkResult",
           "study_table", "study_json"]
