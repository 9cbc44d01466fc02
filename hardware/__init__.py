"""The servo chain: Protocol 2.0 control tables, the driver over dynamixel-sdk, the emulator, fault policy.

Leaf package: imports nothing else of servoface. Servos are integer ids here; roles live above.
"""
