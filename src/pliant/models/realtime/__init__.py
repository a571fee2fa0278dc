"""The real-time model: a force-density bar network on the control polygon of a
B-spline, swept into a tube for display; its forces are fictive."""

from pliant.models.realtime.model import GripRow as GripRow
from pliant.models.realtime.model import RealtimeFrame as RealtimeFrame
from pliant.models.realtime.model import RealtimeModel as RealtimeModel
