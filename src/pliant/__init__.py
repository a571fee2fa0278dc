"""pliant: flexible parts (hoses, pipes, cables) in assembly and disassembly.

The vocabulary (``Part``, ``Problem``, conditions, ``loads``: every load type, as
``pl.loads.AddedMass``) imports at once; the solvers load
numba kernels, so ``solve`` and ``trace`` are imported on first use.
"""

from pliant.core import Branch as Branch
from pliant.core import Condition as Condition
from pliant.core import DistributedLoad as DistributedLoad
from pliant.core import Equilibrium as Equilibrium
from pliant.core import Equilibrium3D as Equilibrium3D
from pliant.core import Junction as Junction
from pliant.core import Material as Material
from pliant.core import Part as Part
from pliant.core import PivotClip as PivotClip
from pliant.core import Problem as Problem
from pliant.core import SlidingClip as SlidingClip
from pliant.core import StationLoad as StationLoad
from pliant.core import Unsolved as Unsolved
from pliant.core import clamp as clamp
from pliant.core import grip as grip
from pliant.core import interpolate as interpolate
from pliant.core import loads as loads
from pliant.core import pin as pin
from pliant.core import push as push

__version__ = "0.1.0"

_LAZY = {"solve": "pliant.models.dispatch", "trace": "pliant.models.dispatch",
         "ShootingSolver": "pliant.models.elastica2d", "RodSolver": "pliant.models.rod3d"}


def __getattr__(name: str):
    if name in _LAZY:
        import importlib  # noqa: PLC0415 (only for a lazy name)

        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'pliant' has no attribute {name!r}")
