"""Test setup shared by the suite.

A process started in the background by a non-interactive shell (`cmd &`, nohup, some CI
runners) inherits SIGINT as *ignored*; Python then installs no KeyboardInterrupt handler and
`_thread.interrupt_main()` does nothing, so the Ctrl-C tests could not see their Ctrl-C. The
tests are about what the binding does when Python's own handler is in place, as it is in an
interactive session, so it is put in place here for every test.
"""

import signal

import pytest


@pytest.fixture(autouse=True)
def python_handles_ctrl_c():
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)
