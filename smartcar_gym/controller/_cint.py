"""C integer arithmetic of the ArbotiX's AVR: 16-bit ``int``, 32-bit ``long``, truncating ``/``."""

from __future__ import annotations


def wrap_int16(n: int) -> int:
    """Wrap ``n`` to a two's-complement 16-bit value, as an AVR ``int`` holds it."""
    return ((n + 0x8000) & 0xFFFF) - 0x8000


def wrap_int32(n: int) -> int:
    """Wrap ``n`` to a two's-complement 32-bit value, as an AVR ``long`` holds it."""
    return ((n + 0x8000_0000) & 0xFFFF_FFFF) - 0x8000_0000


def c_div(a: int, b: int) -> int:
    """C integer division: the quotient truncated toward zero (Python's ``//`` floors)."""
    q = abs(a) // abs(b)
    return q if (a >= 0) == (b > 0) else -q
