"""aidnav: aided inertial navigation from Python.

The Rust library behind the ``aidnav`` command-line tool, called from numpy:

* the estimation engine: :class:`KalmanFilter` (``predict``, ``update``
  returning an :class:`Update` record, ``batch`` for a whole measurement
  array in one call), the measurement policies (:func:`chi2_gate`,
  :func:`huber`, :func:`scheme` for every scheme of the registry) and
  :func:`rts_smooth`;
* the readers of every log format ``process`` reads: :func:`read_imu`,
  :func:`read_gnss` (DataFrames with pandas, dicts of arrays without);
* :func:`process`: a recorded IMU + GNSS log (files or in-memory arrays)
  filtered, smoothed and scored, as :class:`ProcessResult`;
* :func:`reproduce` (a paper reproduction's summary) and
  :func:`monte_carlo` (the same campaign split across a Dask cluster, bit
  for bit the local result; or a list of ``process`` configurations).

Long calls release the GIL and can be interrupted with Ctrl-C; errors are
:class:`AidnavError` subclasses whose message names the file, line, column
or key.
"""

from __future__ import annotations

import os
from typing import Any, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from . import _aidnav
from ._aidnav import (
    AidnavError,
    Campaign,
    ConfigError,
    DataError,
    FilterError,
    KalmanFilter,
    Policy,
    Update,
    experiment_names,
    rts_smooth,
    scheme_defaults,
    scheme_names,
)
from ._tables import columns_of, have_pandas, records, table
from .campaign import monte_carlo, zoo

__version__: str = _aidnav.__version__

PathLike = Union[str, "os.PathLike[str]"]
Config = Union[PathLike, Mapping[str, Any]]

__all__ = [
    "AidnavError",
    "Campaign",
    "ConfigError",
    "DataError",
    "FilterError",
    "KalmanFilter",
    "Policy",
    "ProcessResult",
    "Update",
    "chi2_gate",
    "experiment_names",
    "have_pandas",
    "huber",
    "monte_carlo",
    "process",
    "read_gnss",
    "read_imu",
    "reproduce",
    "rts_smooth",
    "scheme",
    "scheme_defaults",
    "scheme_names",
    "SimulatedLog",
    "simulate",
    "zoo",
]


def chi2_gate(probability: Optional[float] = None) -> Policy:
    """χ² gate: reject an update whose NIS exceeds the χ²(m) quantile of
    ``probability`` (``None``: the engine's default,
    ``scheme_defaults()["chi2_probability"]``)."""
    return Policy.chi2_gate(probability)


def huber(k: Optional[float] = None) -> Policy:
    """Huber re-weighting: R inflated by √NIS / k above k (``None``: the
    engine's default, ``scheme_defaults()["huber_k"]``, 95 % efficiency at
    the normal)."""
    return Policy.huber(k)


def scheme(name: str, **parameters: Any) -> Policy:
    """A robust-estimation scheme of the registry by name (see
    :func:`scheme_names`: ``accept``, ``chi2_gate``, ``recovering_gate``,
    ``huber``, ``rejection``, ``limiting``, ``adaptive_gain``,
    ``limited_adaptive_gain``, ``developed``, ``robust``); keyword
    parameters ``chi2_probability``, ``recovering_after``, ``huber_k``,
    ``anomaly_gamma``, ``adaptive_window``, ``adaptive_diagonal_rule``
    (``"all"`` or ``"any"``), each defaulting to the engine's
    (:func:`scheme_defaults`) and checked against the engine's range
    (``ValueError`` naming the parameter, its value and the range)."""
    return Policy.scheme(name, **parameters)


def read_imu(
    path: PathLike,
    format: str = "generic_csv",
    *,
    tags: Optional[PathLike] = None,
    units: Optional[Mapping[str, str]] = None,
    as_frame: Optional[bool] = None,
):
    """Read an IMU log as ``process`` reads it.

    ``format`` is ``data.imu_format``: ``rtklib_tagged`` (with ``tags``, the
    ``.tag`` file), ``kf_gins`` or ``generic_csv`` (``units`` as
    ``data.imu_units``, e.g. ``{"gyro": "deg_s", "accel": "g"}``). Returns the
    columns ``time_s, gx_rad_s … az_m_s2`` (sensor frame, SI, time as
    recorded) as a DataFrame (``attrs["warnings"]`` holds the reader's
    warnings) or, without pandas or with ``as_frame=False``, as a dict of
    arrays with a ``"warnings"`` entry left out: use :func:`read_imu_with_warnings`.
    Errors (:class:`DataError`) name the file, the line and the column.
    """
    columns, warnings = _aidnav.read_imu(os.fspath(path), format, None if tags is None else os.fspath(tags), units)
    return table(columns, as_frame, {"warnings": warnings})


def read_gnss(
    path: PathLike,
    format: str = "rtklib_pos",
    *,
    sigma_m: Optional[Tuple[float, float]] = None,
    as_frame: Optional[bool] = None,
):
    """Read a GNSS log as ``process`` reads it.

    ``format`` is ``data.gnss_format``: ``rtklib_pos``, ``kf_gins``, ``nmea``,
    ``ubx`` or ``generic_csv`` (``sigma_m = (horizontal, up)`` as
    ``data.gnss_sigma_m``). Columns: ``gpst_s, lat_deg, lon_deg, height_m,
    sigma_n_m, sigma_e_m, sigma_u_m, quality, satellites, vel_n_mps,
    vel_e_mps, vel_d_mps, sigma_vel_n_mps, sigma_vel_e_mps, sigma_vel_u_mps``
    (NaN: no velocity) and ``has_velocity``. Errors as :func:`read_imu`.
    """
    columns, warnings = _aidnav.read_gnss(os.fspath(path), format, None if sigma_m is None else tuple(sigma_m))
    return table(columns, as_frame, {"warnings": warnings})


def read_imu_with_warnings(path: PathLike, format: str = "generic_csv", **options: Any) -> Tuple[Dict[str, np.ndarray], List[str]]:
    """:func:`read_imu` as (dict of arrays, warnings), whatever is installed."""
    tags = options.get("tags")
    return _aidnav.read_imu(os.fspath(path), format, None if tags is None else os.fspath(tags), options.get("units"))


def read_gnss_with_warnings(path: PathLike, format: str = "rtklib_pos", **options: Any) -> Tuple[Dict[str, np.ndarray], List[str]]:
    """:func:`read_gnss` as (dict of arrays, warnings), whatever is installed."""
    sigma = options.get("sigma_m")
    return _aidnav.read_gnss(os.fspath(path), format, None if sigma is None else tuple(sigma))


class ProcessResult:
    """A processed log: what ``aidnav process`` computes, as values.

    Attributes (DataFrames with pandas, dicts of arrays without):

    * ``solution`` – ``solution.csv``'s columns (per GNSS epoch and between);
    * ``smoothed`` – ``smoothed.csv``'s (RTS-smoothed positions; empty
      without ``output.smooth``);
    * ``instruments`` – ``instruments.csv``'s (bias and scale-factor
      estimates per epoch);
    * ``wheel_speed``, ``barometer`` – ``wheel_speed.csv``'s and
      ``barometer.csv``'s (one row per update of those streams: innovation,
      its σ, NIS, outcome; empty without the ``[wheel_speed]`` /
      ``[barometer]`` tables); ``summary["result"]["aid_sources"]`` counts
      every stream's updates;
    * ``scores`` – one row per outage length and solution (``filter``,
      ``smoothed``, ``free_ins``): windows, reference epochs, horizontal,
      vertical and 3-D drift RMS [m] (empty when not scored);
    * ``anomalies`` – RMS under injected anomalies per fraction and policy;
    * ``warnings`` – ``kind``, ``message``, ``start_s``, ``end_s``;
    * ``install`` – the estimated install parameters and sensor errors
      (``summary["result"]["install"]``: GNSS latency, lever arm, vehicle
      misalignment, odometer scale, barometer bias), one row each:
      ``name``, ``unit``, ``value``, ``sigma``, ``prior_sigma``;
    * ``summary`` – ``summary.json`` as a dict (``summary["result"]`` is the
      report).

    :meth:`write` writes the same files as the CLI.
    """

    def __init__(self, native: "_aidnav.ProcessResult", as_frame: Optional[bool] = None) -> None:
        self._native = native
        self._as_frame = as_frame
        self.summary: Dict[str, Any] = native.summary()
        result = self.summary["result"]
        self.solution = table(native.solution(), as_frame)
        self.smoothed = table(native.smoothed(), as_frame)
        self.instruments = table(native.instruments(), as_frame)
        self.wheel_speed = table(native.aid_updates("wheel_speed"), as_frame)
        self.barometer = table(native.aid_updates("barometer"), as_frame)
        rows: List[Dict[str, Any]] = []
        for solution, key in (("filter", "outages"), ("smoothed", "outages_smoothed"), ("free_ins", "outages_free_ins")):
            for score in result.get(key) or []:
                row = {"solution": solution}
                row.update({k: v for k, v in score.items() if not isinstance(v, list)})
                rows.append(row)
        self.scores = records(rows, as_frame)
        self.anomalies = records(
            [{"fraction": f, "policy": p, "rms_3d_m": r} for f, p, r in result.get("anomalies") or []],
            as_frame,
        )
        self.warnings = records(result.get("warnings") or [], as_frame)
        self.install = records(result.get("install") or [], as_frame)

    @property
    def result(self) -> Dict[str, Any]:
        """``summary["result"]``: the report of the run."""
        return self.summary["result"]

    @property
    def scored(self) -> bool:
        """Whether the log was scored (``score=True``)."""
        return bool(self._native.scored)

    def write(self, directory: PathLike) -> List[str]:
        """Write ``solution.csv``, ``smoothed.csv``, ``instruments.csv``, the
        SVG plots and ``summary.json`` into ``directory`` (as ``aidnav
        process``, which also removes an earlier run's ``smoothed.csv``,
        ``navresult.txt`` or ``outage_drift.svg`` when this result has
        none, with a warning in ``summary.json``); returns the files."""
        return [os.fspath(p) for p in self._native.write(os.fspath(directory))]

    def __repr__(self) -> str:
        r = self.result
        return (
            f"ProcessResult(gnss_epochs={r.get('gnss_epochs')}, imu_samples={r.get('imu_samples')}, "
            f"tracking_rms_m={r.get('tracking_rms_m')}, scored={self.scored})"
        )


def process(
    config: Config,
    imu: Any = None,
    gnss: Any = None,
    *,
    base: Optional[PathLike] = None,
    score: bool = True,
    as_frame: Optional[bool] = None,
) -> ProcessResult:
    """Filter, smooth and score a recorded IMU + GNSS log, as ``aidnav process``.

    ``config`` is a TOML file or a dict of the same tables (relative data
    paths start at the file's directory, or at ``base``, or the current
    directory for a dict). ``imu`` / ``gnss`` (DataFrames or dicts of arrays
    with the columns :func:`read_imu` / :func:`read_gnss` return: sensor
    frame, time as recorded) replace the files of ``[data]``; with both
    given, ``[data]`` may be left out. ``score=False`` skips the outage and
    anomaly scoring. Runs with the GIL released; Ctrl-C interrupts it.
    """
    if isinstance(config, Mapping):
        config = dict(config)
        if imu is not None and gnss is not None and "data" not in config:
            config["data"] = {
                "dir": ".",
                "imu": "<in memory>",
                "imu_format": "generic_csv",
                "gnss": "<in memory>",
                "gnss_format": "generic_csv",
            }
    else:
        config = os.fspath(config)
    imu_cols = None if imu is None else columns_of(imu, "imu")
    gnss_cols = None if gnss is None else columns_of(gnss, "gnss")
    if gnss_cols is not None:
        gnss_cols.pop("has_velocity", None)
    native = _aidnav.process_log(config, imu_cols, gnss_cols, None if base is None else os.fspath(base), score)
    return ProcessResult(native, as_frame)


def reproduce(
    name: str,
    runs: Optional[int] = None,
    seed: Optional[int] = None,
    scenario: Optional[Config] = None,
) -> Dict[str, Any]:
    """Run a paper reproduction (:func:`experiment_names`) and return its
    ``summary.json`` as a dict — what ``aidnav reproduce NAME --runs RUNS
    --seed SEED --scenario FILE`` writes. ``scenario`` is a TOML file or a
    dict (None: the defaults). No file is written."""
    if scenario is not None and not isinstance(scenario, Mapping):
        scenario = os.fspath(scenario)
    return Campaign(name, scenario, runs, seed).summary()


class SimulatedLog:
    """A simulated log with its truth (what ``aidnav simulate`` writes, as
    values).

    Attributes (DataFrames with pandas, dicts of arrays without):

    * ``imu`` – IMU samples in IMU axes: ``time_s``, ``gx_rad_s`` …
      ``az_m_s2`` (the columns :func:`read_imu` returns);
    * ``gnss`` – the antenna's fixes (the columns :func:`read_gnss` returns);
    * ``wheel_speed``, ``barometer`` – ``time_s`` with ``speed_mps`` /
      ``height_m`` (empty when the scenario has none);
    * ``truth`` – the IMU's state at every IMU sample: ``time_s``,
      ``latitude_deg``, ``longitude_deg``, ``height_m``,
      ``velocity_north_m_s`` … ``velocity_down_m_s``, ``roll_deg``,
      ``pitch_deg``, ``yaw_deg`` (the reference format of ``truth.csv``);
    * ``installation`` – the planted mounting, lever arms and latency;
    * ``scenario`` – the resolved scenario (TOML text), ``seed``, ``version``.
    """

    def __init__(self, native: Dict[str, Any], as_frame: Optional[bool] = None) -> None:
        self.imu = table(native["imu"], as_frame)
        self.gnss = table(native["gnss"], as_frame)
        self.wheel_speed = table(native["wheel_speed"], as_frame)
        self.barometer = table(native["barometer"], as_frame)
        self.truth = table(native["truth"], as_frame)
        self.installation: Dict[str, Any] = native["installation"]
        self.scenario: str = native["scenario"]
        self.seed: int = native["seed"]
        self.version: str = native["version"]

    def __repr__(self) -> str:
        n = len(self.imu["time_s"])
        return f"SimulatedLog(imu_samples={n}, gnss_epochs={len(self.gnss['gpst_s'])}, seed={self.seed})"


def simulate(scenario: Config, seed: Optional[int] = None, *, as_frame: Optional[bool] = None) -> SimulatedLog:
    """Simulate a scenario (a TOML file as ``aidnav simulate`` takes it, or
    a dict of the same tables), ``seed`` replacing its seed: the streams and
    the truth as tables (:class:`SimulatedLog`). Seeded: the same scenario
    and seed give the same arrays, bit for bit. No file is written."""
    if not isinstance(scenario, Mapping):
        scenario = os.fspath(scenario)
    else:
        scenario = dict(scenario)
    return SimulatedLog(_aidnav.simulate_log(scenario, seed), as_frame)
