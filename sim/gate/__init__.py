"""The twin gate: every servo command is checked on a digital twin of the head before it may reach the bus.

``TwinGate(head, calibration, frame_period_s).check(goals_tick, last_goals_tick, health=None) -> Verdict``.
"""

from servoface.sim.gate.gate import BatchReport, GateConfig, TwinGate
from servoface.sim.gate.health import HealthPolicy, ServoHealth
from servoface.sim.gate.verdict import Finding, Verdict

__all__ = ["BatchReport", "Finding", "GateConfig", "HealthPolicy", "ServoHealth", "TwinGate", "Verdict"]
