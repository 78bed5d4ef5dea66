"""One Ctrl-C that a Python loop never loses: :class:`SigintLatch`.

A SIGINT becomes a KeyboardInterrupt at the next bytecode of the main thread,
wherever that is: inside code whose exceptions CPython or a C extension
discards (a ``__del__``, a weakref or garbage-collector callback, an
attribute probe), the exception is dropped and the loop runs on. The latch
records the signal itself, so the loop's own check raises it there.
"""
from __future__ import annotations

import signal
import threading

__all__ = ["SigintLatch"]


class SigintLatch:
    """Context: while it is open on the main thread, and SIGINT is handled by
    Python's default handler, a SIGINT sets :attr:`hit` and raises
    KeyboardInterrupt as usual; :meth:`check` raises it again where the first
    was discarded. Elsewhere (another thread, a handler of the user's, SIGINT
    ignored) it changes nothing.

    Examples
    --------
    >>> with SigintLatch() as latch:
    ...     latch.check()                 # no SIGINT: nothing happens
    >>> latch.hit
    False
    """

    def __init__(self):
        self.hit = False
        self._old = None

    def _handler(self, signum, frame):
        self.hit = True
        raise KeyboardInterrupt

    def __enter__(self):
        if threading.current_thread() is threading.main_thread() and \
                signal.getsignal(signal.SIGINT) is signal.default_int_handler:
            self._old = signal.signal(signal.SIGINT, self._handler)
        return self

    def check(self):
        """Raise KeyboardInterrupt if a SIGINT arrived and its exception was lost."""
        if self.hit:
            self.hit = False
            raise KeyboardInterrupt

    def __exit__(self, *exc):
        if self._old is not None:
            signal.signal(signal.SIGINT, self._old)
            self._old = None
        return False
