"""The face and its digital twin: head models, AU tables, muscle model, twin gate, collision, rendering.

May import `calibration` (the twin inverts calibration to pose itself); nothing else of servoface.
"""
