"""Tracking a running device on its fitted model: a Kalman filter, a change detector, and the parameter that moved."""

from torchpaml._track.tracker import Alarm, Tracker, Tracking, track

__all__ = ["Alarm", "Tracker", "Tracking", "track"]
