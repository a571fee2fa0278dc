"""The accurate 2D model: the paper's inextensible elastica as a boundary value problem."""

from pliant.models.elastica2d.solver import ShootingSolver as ShootingSolver
from pliant.models.elastica2d.solver import equilibria as equilibria
from pliant.models.elastica2d.solver import solve as solve
from pliant.models.elastica2d.solver import trace as trace
