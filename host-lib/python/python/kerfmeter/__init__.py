"""Measure a laser cutter's kerf with a Kerfmeter, and dilate cutting plans by it.

The three calls of the paper, on a device or on its digital twin in this process::

    import kerfmeter
    with kerfmeter.Kerfmeter.sim(kerf_um=200) as m:   # or Kerfmeter.open("/dev/ttyACM0")
        m.reset_kerfmeter()
        result = m.run_kerfmeter(thickness_mm=4)
        print(result.kerf_um, m.get_kerf_value().kerf_um)

Every error is a :class:`KerfmeterError` (``CommunicationError``, ``DeviceError`` and its
``DeviceFaultError``, ``BadArgumentError``, ``PlanError``) whose message says what to do.
The work is done by the Rust library ``kerfmeter`` and the plan crate ``kerfmeter-plan``.
"""

from importlib.metadata import PackageNotFoundError, version

from ._kerfmeter import (
    BadArgumentError,
    CommunicationError,
    DeviceError,
    DeviceFaultError,
    Kerfmeter,
    KerfmeterError,
    KerfResult,
    Measurement,
    PlanError,
    dilate,
    gauge,
)

try:
    __version__ = version("kerfmeter")
except PackageNotFoundError:  # imported from a source tree, not installed
    __version__ = "unknown"

__all__ = [
    "BadArgumentError",
    "CommunicationError",
    "DeviceError",
    "DeviceFaultError",
    "Kerfmeter",
    "KerfmeterError",
    "KerfResult",
    "Measurement",
    "PlanError",
    "dilate",
    "gauge",
]
