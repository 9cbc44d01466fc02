"""Timelines: Barker's pose -> movement -> expression -> sequence, envelopes with easing, DFACS ordered
events, parallel tracks with per-AU blend rules. Sampling is a pure function of time."""

from servoface.controller.timeline.barker import Expression, Movement, sequence
from servoface.controller.timeline.blend import BlendPolicy, BlendRule
from servoface.controller.timeline.clip import ChannelClip, Clip, Key, SequenceClip
from servoface.controller.timeline.dfacs import Event, EventTiming, events_clip, parse_events, recipe_events
from servoface.controller.timeline.easing import EASINGS, ease_in_out, easing_by_name, linear, min_jerk
from servoface.controller.timeline.envelope import Envelope, EnvelopeClip
from servoface.controller.timeline.timeline import Layer, Timeline
from servoface.controller.timeline.track import Placed, Track

__all__ = [
    "EASINGS",
    "BlendPolicy",
    "BlendRule",
    "ChannelClip",
    "Clip",
    "Envelope",
    "EnvelopeClip",
    "Event",
    "EventTiming",
    "Expression",
    "Key",
    "Layer",
    "Movement",
    "Placed",
    "SequenceClip",
    "Timeline",
    "Track",
    "ease_in_out",
    "easing_by_name",
    "events_clip",
    "linear",
    "min_jerk",
    "parse_events",
    "recipe_events",
    "sequence",
]
