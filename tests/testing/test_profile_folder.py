"""A head from a profile folder of one's own (a copy of the built-in dog here), configured by overriding the
``servoface_config`` fixture: the chain has exactly that profile's servos, and a Face drives it safely."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from servoface.testing import ServofaceConfig

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def my_head(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("profiles") / "my_dog"
    shutil.copytree(ROOT / "sim" / "heads" / "dog", folder)
    return folder


@pytest.fixture
def servoface_config(my_head: Path) -> ServofaceConfig:
    return ServofaceConfig(head=str(my_head))


def test_the_chain_is_the_profiles(servo_chain, servo_specs, calibration, head, my_head: Path) -> None:  # type: ignore[no-untyped-def]
    assert head.name == "dog" and calibration.head == "dog"
    assert servo_chain.ids == [s.servo_id for s in servo_specs] == [a.servo.id for a in head.actuators]
    assert {s.model for s in servo_specs} >= {"XL330-M288", "XL430-W250", "XM430-W350"}
    for s in servo_specs:  # powered up at rest
        assert servo_chain.read_register(s.servo_id, "Present Position") == calibration.by_id(s.servo_id).neutral_tick


def test_a_face_of_the_profile_stays_safe(face, servo_wire) -> None:  # type: ignore[no-untyped-def]
    face.express("happiness", hold_s=0.3)
    servo_wire.assert_safe()
    servo_wire.assert_matches_twin(face, tolerance_tick=1, within_s=2.0)
