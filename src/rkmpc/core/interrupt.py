"""Ctrl-C that ends a run even when a C library (CasADi, IPOPT) swallows it.

Python raises :class:`KeyboardInterrupt` from its SIGINT handler at the next bytecode; when that
happens inside a callback of a C library, the library may catch it and carry on (CasADi's SWIG
wrappers clear it while converting arguments; IPOPT turns it into a failed solve). Within
:func:`interruptible`, SIGINT also sets a flag that :func:`check_interrupted` turns into a
:class:`KeyboardInterrupt` at the next safe point (every controller step calls it), so the run
ends there whatever the library did with the first one.
"""

from __future__ import annotations

import contextlib
import signal
import threading
from collections.abc import Iterator
from types import FrameType

__all__ = ["check_interrupted", "interruptible"]

_pending = threading.Event()


def check_interrupted() -> None:
    """Raise :class:`KeyboardInterrupt` when a SIGINT arrived within :func:`interruptible`."""
    if _pending.is_set():
        raise KeyboardInterrupt


def _handler(signum: int, frame: FrameType | None) -> None:
    _pending.set()
    raise KeyboardInterrupt


@contextlib.contextmanager
def interruptible() -> Iterator[None]:
    """Within the block, Ctrl-C is remembered until it ends the run (module docstring).

    Only in the main thread (elsewhere signal handlers cannot be set, and the block does nothing).
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, _handler)
    _pending.clear()
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        _pending.clear()
