"""Type stubs of the native module (see the docstrings at run time for details)."""

from os import PathLike
from types import TracebackType
from typing import Any, Callable, Dict, List, Optional, Type, Union

_Path = Union[str, "PathLike[str]"]
_Progress = Callable[[str, float, float], object]

class KerfmeterError(Exception):
    """Every error of this package."""

class CommunicationError(KerfmeterError):
    """The link to the device failed: the port, a timeout, the protocol, a restarted device."""

class DeviceError(KerfmeterError):
    """The device refused a request, or could not finish it."""

class DeviceFaultError(DeviceError):
    """The device stopped on a fault and latched it."""

    fault: str
    """The fault's name, e.g. "NoMotion"."""

class BadArgumentError(KerfmeterError, ValueError):
    """A bad argument or parameter; the message names it and its allowed range."""

class PlanError(KerfmeterError):
    """A cutting plan or another file could not be read, dilated or written."""

class KerfResult:
    """The result of a run, as the device keeps it."""

    @property
    def run_id(self) -> int: ...
    @property
    def kerf_um(self) -> float:
        """Kerf (full cut width), µm."""
    @property
    def angle_deg(self) -> float:
        """Hub angle at the jam, degrees."""
    @property
    def play_deg(self) -> float:
        """Hole play included in angle_deg, degrees."""
    @property
    def torque_at_jam_nm(self) -> float:
        """Output torque at the jam, N·m."""
    @property
    def force_at_jam_n(self) -> float:
        """Joint assembly force that torque represents, N."""
    @property
    def flags(self) -> List[str]:
        """Reasons to distrust the number (empty when there are none)."""

class Measurement:
    """Repeated runs and their summary."""

    @property
    def runs(self) -> List[KerfResult]: ...
    @property
    def n(self) -> int: ...
    @property
    def mean_um(self) -> float: ...
    @property
    def sd_um(self) -> float: ...
    @property
    def ci95_um(self) -> Optional[float]:
        """Half-width of the 95 % confidence interval of the mean, µm (None for one run)."""
    @property
    def min_um(self) -> float: ...
    @property
    def max_um(self) -> float: ...
    @property
    def outliers(self) -> List[int]: ...

class Kerfmeter:
    """A Kerfmeter: on a serial port, or the digital twin in this process."""

    @staticmethod
    def open(port: str, timeout_ms: int = 300) -> Kerfmeter: ...
    @staticmethod
    def discover(timeout_ms: int = 300) -> Kerfmeter: ...
    @staticmethod
    def sim(
        kerf_um: float = 150.0,
        seed: int = 1,
        fault: Optional[str] = None,
        kerf_sd_um: float = 0.0,
        realtime: bool = False,
        encoder_on_motor_shaft: bool = False,
        **plant: float,
    ) -> Kerfmeter: ...
    def run_kerfmeter(
        self,
        thickness_mm: float = 4.0,
        force_n: Optional[float] = None,
        fingers: int = 3,
        finger_length_mm: float = 6.3,
        progress: Optional[_Progress] = None,
    ) -> KerfResult:
        """Reset the hub if needed, run and return the result. `progress(state, torque_nm,
        angle_deg)` is called at every 20 ms status poll, during the reset too, and must return
        quickly (the device stops on HostSilent after 1 s without a poll); it must not call
        this meter (KerfmeterError) except `abort()`. Ctrl-C on the main thread, or an exception
        from `progress`, aborts the run (motor stopped) and is raised. `force_n=None` is
        18.3 N per finger."""
    def get_kerf_value(self) -> Optional[KerfResult]: ...
    def reset_kerfmeter(self) -> None: ...
    def measure(
        self,
        n: int,
        thickness_mm: float = 4.0,
        force_n: Optional[float] = None,
        fingers: int = 3,
        finger_length_mm: float = 6.3,
        before_gauge: Optional[Callable[[int], object]] = None,
        progress: Optional[_Progress] = None,
    ) -> Measurement: ...
    def info(self) -> Dict[str, Any]: ...
    def status(self) -> Dict[str, Any]: ...
    def abort(self) -> None:
        """Stop the motor now. While a call runs (in another thread, or from its `progress`),
        that call stops at its next poll and raises DeviceError."""
    def clear_fault(self) -> None: ...
    def confirm_hub_at_zero(self) -> None:
        """Say the hub stands at its zero mark (encoder on the motor shaft, after power-up)."""
        ...
    def self_test(self) -> Dict[str, Any]: ...
    def close(self) -> None: ...
    def __enter__(self) -> Kerfmeter: ...
    def __exit__(
        self,
        exc_type: Optional[Type[BaseException]],
        exc: Optional[BaseException],
        tb: Optional[TracebackType],
    ) -> None: ...

def dilate(
    in_path: _Path,
    out_path: Optional[_Path],
    kerf_um: float,
    *,
    map: Optional[_Path] = None,
    dry_run: bool = False,
    strict: bool = False,
    cut_colors: List[str] = ...,
    cut_max_width_mm: float = 0.3,
    cut_layers: List[str] = ...,
    units: Optional[str] = None,
    if_compensated: str = "refuse",
    force: bool = False,
) -> Dict[str, Any]: ...
def gauge(
    out_path: _Path,
    *,
    jam_direction: str = "cw",
    label: bool = False,
    test_piece_kerf_um: Optional[float] = None,
    thickness_mm: float = 4.0,
    finger_width_mm: float = 6.3,
) -> Dict[str, Any]: ...
