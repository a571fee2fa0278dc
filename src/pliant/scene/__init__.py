"""Scenes: the obstacles around the part, their distance fields, and what the part
touches."""

from pliant.scene.distance import DistanceField, Obstacle
from pliant.scene.interference import Interference
from pliant.scene.interference import of_curve as interference_of_curve
from pliant.scene.interference import of_equilibrium as interference

__all__ = ["DistanceField", "Interference", "Obstacle", "interference",
           "interference_of_curve"]
