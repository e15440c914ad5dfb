"""Shared helpers of the socket tests: wait for a condition, and fail a test that leaks threads.

Import both into a test module (``from _threads import no_leaked_threads, wait_for``); the fixture
is autouse there.
"""

from __future__ import annotations

import threading
import time

import pytest

#: Default wait for a condition on loopback [s] (generous: the CI machine has 2 shared cores).
WAIT_S = 5.0
#: Poll period of :func:`wait_for` [s].
POLL_S = 0.002


def wait_for(cond, timeout: float = WAIT_S) -> bool:
    """Poll ``cond()`` until it is true or ``timeout`` [s] passes; return its last value."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if cond():
            return True
        time.sleep(POLL_S)
    return cond()


@pytest.fixture(autouse=True)
def no_leaked_threads():
    """Every thread a test starts must be gone (joined) within 2 s of its end."""
    before = set(threading.enumerate())
    yield
    assert wait_for(lambda: not (set(threading.enumerate()) - before), 2.0), \
        f"threads left running: {set(threading.enumerate()) - before}"
