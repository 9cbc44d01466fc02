"""Software emulator of a Dynamixel Protocol 2.0 servo chain: the far end of the wire.

Deliberately independent of dynamixel-sdk and of servoface's driver code: its packet code and register
maps are a second transcription of the e-manual, so one wrong address cannot pass its own test.
"""
