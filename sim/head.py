"""A loaded head: the rig (joints, rigid parts, skin), its muscles, actuators and profile data.

Built by :func:`servoface.sim.heads.load_head` from a profile folder (``head.toml`` + meshes); every field is
validated there, so a ``Head`` in hand is consistent (parents exist, joints are in parent-first order,
actuators name existing joints and skin vertices, servo ids are unique).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from servoface.sim.rig import (
    Actuator,
    AnchorActuator,
    CouplingRule,
    FaceType,
    Joint,
    JointActuator,
    Muscle,
    RigidPart,
    Skin,
    Vec3,
)


@dataclass(frozen=True)
class Head:
    """A head profile, loaded and validated.

    joints: parent-first order (a joint's parent always comes before it).
    skin_joint: the joint that carries the skin where no other bind applies (e.g. ``neck_roll``).
    landmarks_mm: named points of the rest head (eye centres, mouth corners, ...) for other modules.
    """

    name: str
    face_type: FaceType
    joints: tuple[Joint, ...]
    parts: tuple[RigidPart, ...]
    skin: Skin
    muscles: tuple[Muscle, ...]
    actuators: tuple[Actuator, ...]
    coupling_rules: tuple[CouplingRule, ...] = ()
    skin_joint: str | None = None
    au_table_path: Path | None = None
    expressions_path: Path | None = None
    calibration_path: Path | None = None
    profile_dir: Path | None = None
    landmarks_mm: dict[str, Vec3] = field(default_factory=dict)
    au_direct_path: Path | None = None  # the direct AU -> actuator-target table (sim/au/direct.py), if any
    # role -> where the profile sets the actuator's target range, for messages: "head.toml: joint[1].limits_deg"
    range_sources: dict[str, str] = field(default_factory=dict)

    # --- lookups ----------------------------------------------------------------------------------------

    @cached_property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(j.name for j in self.joints)

    @cached_property
    def joint_index(self) -> dict[str, int]:
        return {j.name: i for i, j in enumerate(self.joints)}

    def joint(self, name: str) -> Joint:
        """The joint called ``name`` (KeyError names the known joints)."""
        try:
            return self.joints[self.joint_index[name]]
        except KeyError:
            raise KeyError(f"head {self.name!r} has no joint {name!r}; joints: {list(self.joint_names)}") from None

    def part(self, name: str) -> RigidPart:
        for p in self.parts:
            if p.name == name:
                return p
        raise KeyError(f"head {self.name!r} has no part {name!r}; parts: {[p.name for p in self.parts]}")

    def actuator(self, role: str) -> Actuator:
        for a in self.actuators:
            if a.role == role:
                return a
        raise KeyError(f"head {self.name!r} has no actuator {role!r}; roles: {list(self.roles)}")

    def muscle(self, name: str) -> Muscle:
        for m in self.muscles:
            if m.name == name:
                return m
        raise KeyError(f"head {self.name!r} has no muscle {name!r}; muscles: {[m.name for m in self.muscles]}")

    @cached_property
    def roles(self) -> tuple[str, ...]:
        return tuple(a.role for a in self.actuators)

    @cached_property
    def joint_actuators(self) -> tuple[JointActuator, ...]:
        return tuple(a for a in self.actuators if isinstance(a, JointActuator))

    @cached_property
    def anchor_actuators(self) -> tuple[AnchorActuator, ...]:
        return tuple(a for a in self.actuators if isinstance(a, AnchorActuator))

    @cached_property
    def servo_ids(self) -> dict[str, int]:
        """role -> Dynamixel id."""
        return {a.role: a.servo.id for a in self.actuators}

    @cached_property
    def neutral_joint_deg(self) -> dict[str, float]:
        return {j.name: j.neutral_deg for j in self.joints}

    @property
    def has_skin(self) -> bool:
        """False for a purely mechanical head (rigid parts on joints only; its skin arrays are empty)."""
        return int(self.skin.vertices_mm.shape[0]) > 0

    @property
    def n_skin_vertices(self) -> int:
        return int(self.skin.vertices_mm.shape[0])

    def skin_vertex_mm(self, index: int) -> NDArray[np.float64]:
        """(3,) float: rest position of one skin vertex."""
        return np.asarray(self.skin.vertices_mm[index], dtype=np.float64)
