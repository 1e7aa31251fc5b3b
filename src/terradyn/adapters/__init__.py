"""Adapters that put terradyn's granular forces into other simulators.

* :mod:`terradyn.adapters.mujoco` - granular terrain (3D RFT) for MuJoCo robot models
  (optional extra ``terradyn[mujoco]``); demo robot and walking study in
  :mod:`terradyn.adapters.mujoco_demo`.
"""
