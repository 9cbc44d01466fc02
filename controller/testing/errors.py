"""Errors of the test kit (``servoface.testing``): a bad configuration or a served chain that broke."""


class TestKitError(Exception):
    """Base of every error raised by servoface's test kit (not a test failure: those are AssertionError)."""

    __test__ = False  # not a test class, whatever pytest's name rules say


class TestKitConfigError(TestKitError, ValueError):
    """A marker, option, ini value or fixture argument is invalid (names it and what was expected)."""


class ServedChainError(TestKitError):
    """The emulator process serving a pty failed to start, answered an error or died (carries its stderr)."""
