"""The shared vocabulary: parts, conditions, problems and equilibria (SI units)."""

from pliant.core.conditions import Condition as Condition
from pliant.core.conditions import clamp as clamp
from pliant.core.conditions import grip as grip
from pliant.core.conditions import pin as pin
from pliant.core.conditions import push as push
from pliant.core.equilibrium import Equilibrium as Equilibrium
from pliant.core.equilibrium import Equilibrium3D as Equilibrium3D
from pliant.core.equilibrium import Result as Result
from pliant.core.equilibrium import StationLoad as StationLoad
from pliant.core.equilibrium import Unsolved as Unsolved
from pliant.core.loads import DistributedLoad as DistributedLoad
from pliant.core.part import Material as Material
from pliant.core.part import Part as Part
from pliant.core.problem import Branch as Branch
from pliant.core.problem import Junction as Junction
from pliant.core.problem import PivotClip as PivotClip
from pliant.core.problem import Problem as Problem
from pliant.core.problem import SlidingClip as SlidingClip
from pliant.core.problem import interpolate as interpolate
