"""Alive behaviours as timeline layers: spontaneous blinks, gaze / look-at with eye-head coordination,
idle motion."""

from servoface.controller.alive.blink import BlinkConfig, BlinkLayer
from servoface.controller.alive.gaze import GazeConfig, GazePose, solve_look_at
from servoface.controller.alive.gaze_layer import GazeLayer, angles_to_aus
from servoface.controller.alive.idle import IdleConfig, IdleLayer

__all__ = [
    "BlinkConfig",
    "BlinkLayer",
    "GazeConfig",
    "GazeLayer",
    "GazePose",
    "IdleConfig",
    "IdleLayer",
    "angles_to_aus",
    "solve_look_at",
]
