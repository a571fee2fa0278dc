"""Scenes: the obstacles around the part, their distance fields, and what the part
touches."""

from pliant.scene.distance import DistanceField as DistanceField
from pliant.scene.distance import Obstacle as Obstacle
