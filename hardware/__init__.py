"""The servo chain: Protocol 2.0 control tables, the driver over dynamixel-sdk, the emulator, fault policy.

Leaf package: imports nothing else of servoface. Servos are integer ids here; roles live above.

Driver side, one idea per module (nothing is imported here, so ``import servoface.hardware`` stays cheap):

- ``registers``      control-table fields as an enum (address, size, sign, area), models, error bits
- ``bus``            the `ServoBus` interface and ``open_bus(name, ...)``; ``dynamixel_bus`` the only SDK user
- ``latency``        USB latency timer check and advice; ``wire`` wire-time arithmetic of a cycle
- ``servo_config``   `ServoSpec` descriptions and verified configuration; ``scan`` ping/broadcast scans
- ``driver``         `Driver.cycle(goals) -> ChainSnapshot`; ``driver_thread`` a background owner thread
- its parts: ``driver_reads``, ``goal_check``, ``fault_policy``, ``fault_reactions``, ``servo_record``,
  ``snapshot``
- ``emulator/``      the far end of the wire (independent transcription; see its README section)
"""
