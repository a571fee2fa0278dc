"""Assembly and disassembly operations: a grip carried along a path through a scene,
step by step, with what the hand feels and what the part touches."""

from pliant.assembly.path import PathRun as PathRun
from pliant.assembly.path import StepRecord as StepRecord
from pliant.assembly.path import follow_path as follow_path
from pliant.assembly.scenes import load_scene as load_scene
from pliant.assembly.scenes import parse_scene as parse_scene
from pliant.assembly.scenes import scene_from_data as scene_from_data
