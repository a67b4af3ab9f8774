"""frenet-eot tracker: extended object tracking of vehicles in curvilinear road coordinates.

numpy, scipy and numba only; never imports ``sim``. A user with real data needs only this package.
"""

from tracker.config import TrackerConfig
from tracker.frame import EgoState, Frame, RadarDetections
from tracker.lanes import LaneLayout
from tracker.road import Road
from tracker.tracker import Tracker
from tracker.track import Track

__all__ = ["EgoState", "Frame", "LaneLayout", "RadarDetections", "Road", "Track", "Tracker", "TrackerConfig"]
