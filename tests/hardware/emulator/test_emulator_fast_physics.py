"""Issue 17: the emulator's obstacle-free physics fast path (`physics.free_load`) gives the same numbers as
the plain path (`physics.load_fraction` with its obstacle checks), on random states and random moves."""

from __future__ import annotations

import random

from servoface.hardware.emulator import ServoChain, physics


def test_free_load_equals_load_fraction_without_obstacle() -> None:
    rng = random.Random(17)
    for _ in range(5000):
        pos = rng.choice([2048.0, rng.uniform(-5000.0, 9000.0)])
        target = rng.choice([pos, rng.uniform(-5000.0, 9000.0), pos + rng.choice([-1e-7, 1e-7])])
        vel = rng.choice([0.0, rng.uniform(-3000.0, 3000.0)])
        accel = rng.choice([0.0, rng.uniform(-1e6, 1e6), rng.uniform(-1e4, 1e4)])
        state = physics.MotorState(pos=pos, vel=vel, target=target)
        plain = physics.load_fraction(state, True, None, accel)
        assert physics.free_load(vel, target - pos, accel) == plain


def test_free_motion_matches_the_plain_loop_on_random_moves() -> None:
    """Servo 1 takes the fast path (no obstacle); servo 2 the plain one (a wall far out of reach, so it never
    matters): every register and the motor state stay identical over random goals, profiles and steps."""
    rng = random.Random(5)
    chain = ServoChain.create(ids=[1, 2], model="XL330-M288", wire_time=False, clock="manual")
    fast, plain = chain.servo(1), chain.servo(2)
    chain.set_obstacle(2, at_tick=-1e9)
    for s in (fast, plain):
        s.write_register("Torque Enable", 1)
    for _ in range(400):
        goal = rng.randrange(0, 4096)
        vel = rng.choice([0, rng.randrange(1, 300)])
        acc = rng.choice([0, rng.randrange(1, 200)])
        for s in (fast, plain):
            s.write_register("Profile Velocity", vel)
            s.write_register("Profile Acceleration", acc)
            s.write_register("Goal Position", goal)
        chain.advance(rng.choice([0.0004, 0.0014, 0.003, 0.05, 0.3]))
        assert fast.motor == plain.motor
        assert fast.read_bytes(120, 27) == plain.read_bytes(120, 27)
