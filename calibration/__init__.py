"""Servo calibration: curves from actuator targets (deg or mm) to goal ticks and back, files, procedure.

Leaf package: imports nothing else of servoface. The procedure is handed a bus by its caller.
"""
