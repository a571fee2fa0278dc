"""The coupling layer: grip events -> real-time frames -> accurate solves -> retuning."""

from pliant.session.accurate import AccurateResult as AccurateResult
from pliant.session.session import Drift as Drift
from pliant.session.session import Frame as Frame
from pliant.session.session import GripEvent as GripEvent
from pliant.session.session import Session as Session
from pliant.session.session import replay as replay
