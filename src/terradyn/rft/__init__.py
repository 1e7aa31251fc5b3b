"""Resistive force theory (Li, Zhang & Goldman 2013) for 2D legs in planar motion."""
from .api import simulate, simulate_many
from .engine import ElementStates, PackedElements, batch_forces, element_forces, element_states, net_forces

__all__ = ["simulate", "simulate_many", "ElementStates", "PackedElements", "batch_forces",
           "element_forces", "element_states", "net_forces"]
