"""Type stubs of the extension module ``aidnav._aidnav`` (see the package's
docstrings for the user-facing API)."""

from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple, Union
import os

import numpy as np
import numpy.typing as npt

__version__: str

_Path = Union[str, "os.PathLike[str]"]
_F64 = npt.NDArray[np.float64]

class AidnavError(Exception):
    """Base class of aidnav's errors; the message names the file, line, column or key."""

class ConfigError(AidnavError):
    """A configuration or scenario is malformed or out of range: ``path:line: key: message``."""

class DataError(AidnavError):
    """A data file or in-memory data cannot be used: ``path:line: column `name`: message``."""

class FilterError(AidnavError):
    """The engine refused a step, naming the step, the matrix and the epoch."""

class Policy:
    """A measurement policy (χ² gate, Huber, or a scheme of the registry); keeps its state across updates."""
    @staticmethod
    def scheme(
        name: str,
        *,
        chi2_probability: Optional[float] = None,
        recovering_after: Optional[int] = None,
        huber_k: Optional[float] = None,
        anomaly_gamma: Optional[float] = None,
        adaptive_window: Optional[int] = None,
        adaptive_diagonal_rule: Optional[str] = None,
    ) -> "Policy": ...
    @staticmethod
    def chi2_gate(probability: Optional[float] = None) -> "Policy": ...
    @staticmethod
    def huber(k: Optional[float] = None) -> "Policy": ...
    @property
    def name(self) -> str: ...
    @property
    def noise_rule(self) -> str: ...
    @property
    def parameters(self) -> Dict[str, float]: ...
    def reset(self) -> None: ...

class Update:
    """What one measurement update did."""
    @property
    def residual(self) -> _F64: ...
    @property
    def S(self) -> _F64: ...
    @property
    def gain(self) -> _F64: ...
    @property
    def nis(self) -> float: ...
    @property
    def outcome(self) -> str: ...
    @property
    def log_likelihood(self) -> float: ...

class KalmanFilter:
    """A linear Kalman filter: Joseph-form update, Cholesky-solved gain, checked steps."""
    def __init__(self, x0: npt.ArrayLike, P0: npt.ArrayLike, joseph: bool = True) -> None: ...
    x: _F64
    P: _F64
    @property
    def dim(self) -> int: ...
    def predict(self, F: npt.ArrayLike, Q: npt.ArrayLike) -> None: ...
    def update(self, z: npt.ArrayLike, H: npt.ArrayLike, R: npt.ArrayLike, policy: Optional[Policy] = None) -> Update: ...
    def batch(
        self,
        zs: npt.ArrayLike,
        F: npt.ArrayLike,
        Q: npt.ArrayLike,
        H: npt.ArrayLike,
        R: npt.ArrayLike,
        policy: Optional[Policy] = None,
        predict_first: bool = True,
        covariances: bool = False,
        smooth: bool = False,
    ) -> Dict[str, Any]:
        """Every row of ``zs`` (epochs × m, NaN: missing) in one call, the
        GIL released: predict with (F, Q), update with the components
        present under ``policy``. Each epoch's update runs in fixed-size
        matrices (≤ 6 components present; 1–6, 9, 12, 15, 18, 21, 24
        states), allocating nothing without a policy. Once an accepted
        update leaves P bit for bit as one of the last four epochs' with
        the same components present (the Riccati recursion's fixed point,
        or a cycle of two to four covariances, reached by some
        time-invariant models), the following epochs with the same
        components present and an accepted update compute the state only —
        the same numbers, bit for bit; ``steady_epochs`` in the result
        counts them. F, Q, H and R are checked once per call (each epoch
        checks what changes: z, x, P)."""
    def copy(self) -> "KalmanFilter": ...

def rts_smooth(
    x_filtered: npt.ArrayLike,
    P_filtered: npt.ArrayLike,
    x_predicted: npt.ArrayLike,
    P_predicted: npt.ArrayLike,
    F: npt.ArrayLike,
) -> Dict[str, _F64]: ...
def scheme_names() -> List[str]: ...
def scheme_defaults() -> Dict[str, Any]: ...
def experiment_names() -> List[str]: ...
def read_imu(
    path: _Path, format: str = "generic_csv", tags: Optional[_Path] = None, units: Optional[Mapping[str, str]] = None
) -> Tuple[Dict[str, _F64], List[str]]: ...
def read_gnss(
    path: _Path, format: str = "rtklib_pos", sigma_m: Optional[Tuple[float, float]] = None
) -> Tuple[Dict[str, npt.NDArray[Any]], List[str]]: ...

class ProcessResult:
    """A processed log, before anything is written."""
    def solution(self) -> Dict[str, _F64]: ...
    def smoothed(self) -> Dict[str, _F64]: ...
    def instruments(self) -> Dict[str, _F64]: ...
    def aid_updates(self, source: str) -> Dict[str, _F64]: ...
    def summary(self) -> Dict[str, Any]: ...
    def write(self, dir: _Path) -> List[str]: ...
    @property
    def scored(self) -> bool: ...

def process_log(
    config: Union[_Path, Mapping[str, Any]],
    imu: Optional[Mapping[str, npt.ArrayLike]] = None,
    gnss: Optional[Mapping[str, npt.ArrayLike]] = None,
    base: Optional[_Path] = None,
    score: bool = True,
) -> ProcessResult: ...

def simulate_log(scenario: Union[_Path, Mapping[str, Any]], seed: Optional[int] = None) -> Dict[str, Any]: ...
def zoo_entry(scenario: Union[_Path, Mapping[str, Any]], seed: Optional[int] = None) -> Dict[str, Any]: ...

class Campaign:
    """A reproduction's Monte Carlo campaign, whole or in chunks of runs."""
    def __init__(
        self,
        name: str,
        scenario: Optional[Union[_Path, Mapping[str, Any]]] = None,
        runs: Optional[int] = None,
        seed: Optional[int] = None,
        *,
        scenario_text: Optional[str] = None,
        origin: Optional[_Path] = None,
    ) -> None: ...
    @property
    def name(self) -> str: ...
    @property
    def runs(self) -> int: ...
    @property
    def splits(self) -> bool:
        """Whether the runs can be computed in chunks (every reproduction's can)."""
    def summary(self) -> Dict[str, Any]:
        """The whole campaign here (Ctrl-C stops it within a run)."""
    def run_chunk(self, start: int, end: int) -> bytes: ...
    def finish(self, chunks: Sequence[bytes]) -> Dict[str, Any]: ...

def _running_calls() -> int:
    """Long Rust calls whose work is still running (cancelled ones included)."""
