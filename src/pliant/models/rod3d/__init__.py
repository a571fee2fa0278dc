"""The accurate 3D model: a discrete inextensible Kirchhoff rod (bending and torsion)."""

from pliant.models.rod3d.shapes import from_shape as from_shape
from pliant.models.rod3d.solver import RodSolver as RodSolver
from pliant.models.rod3d.solver import equilibria as equilibria
from pliant.models.rod3d.solver import solve as solve
from pliant.models.rod3d.solver import trace as trace
from pliant.models.rod3d.together import solved_alone as solved_alone
