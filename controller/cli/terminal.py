"""Text for the operator's terminal: anything that came from outside (AU names, file contents, messages)
is shown with control characters escaped, so an ANSI escape or a lone surrogate can neither repaint the
terminal nor crash the closing report."""

from __future__ import annotations

import re

_CONTROL = re.compile(r"[\x00-\x08\x0b-\x1f\x7f-\x9f\u2028\u2029\u200e\u200f\u202a-\u202e\u2066-\u2069]")


def printable(text: object) -> str:
    """``str(text)`` with C0/C1 controls, bidi overrides and lone surrogates escaped (``\\x1b``, ``\\ud800``);
    newlines and tabs are kept."""
    s = str(text)
    s = s.encode("utf-8", "backslashreplace").decode("utf-8")  # lone surrogates -> \\udxxx
    return _CONTROL.sub(lambda m: m.group(0).encode("unicode_escape").decode("ascii"), s)
