"""aidnav.simulate and the zoo from Python: the streams with their truth,
seeded; the zoo's entries the same here and on two Dask workers."""

import numpy as np
import pytest

import aidnav

from conftest import ROOT

ZOO = ROOT / "zoo"
SHORT = [ZOO / "short_car_baseline.toml", ZOO / "short_walk_consumer.toml"]


def test_simulate_gives_the_streams_and_the_truth():
    log = aidnav.simulate(SHORT[0], as_frame=False)
    imu, gnss, truth = log.imu, log.gnss, log.truth
    assert len(imu["time_s"]) == len(truth["time_s"]) > 10_000
    assert np.array_equal(imu["time_s"], truth["time_s"])
    # Standing still at first: the accelerometers read about -g on z.
    assert abs(np.median(imu["az_m_s2"][:1000]) + 9.79) < 0.05
    # The fixes lie near the truth (single point, metres).
    k = np.searchsorted(truth["time_s"], gnss["gpst_s"][50])
    assert abs(gnss["lat_deg"][50] - truth["latitude_deg"][k]) * 111e3 < 15.0
    assert log.seed == 1 and log.version == aidnav.__version__
    assert log.installation["mounting_deg"] == [0.0, 0.0, 0.0]
    again = aidnav.simulate(SHORT[0], as_frame=False)
    assert all(np.array_equal(again.imu[c], imu[c]) for c in imu)
    other = aidnav.simulate(SHORT[0], seed=5, as_frame=False)
    assert not np.array_equal(other.imu["gx_rad_s"], imu["gx_rad_s"])


def test_simulate_takes_a_dict_and_names_bad_keys():
    log = aidnav.simulate(
        {"name": "d", "route_preset": "rover", "gnss": {"mode": "fixed", "rate_hz": 5.0}},
        as_frame=False,
    )
    assert np.allclose(np.diff(log.gnss["gpst_s"]), 0.2)
    with pytest.raises(aidnav.ConfigError, match="rate_hz"):
        aidnav.simulate({"gnss": {"rate_hz": -1.0}})


def test_a_simulated_log_processes_from_memory():
    log = aidnav.simulate(SHORT[0], as_frame=False)
    gnss = {k: v for k, v in log.gnss.items() if k not in ("has_velocity",)}
    result = aidnav.process({"platform": "car"}, imu=log.imu, gnss=gnss, score=False)
    assert result.result["gnss_epochs"] == len(log.gnss["gpst_s"])


def test_the_install_estimates_are_a_table():
    # The zoo's car with its IMU pitched 3° against the car: the vehicle
    # frame's pitch estimated through the non-holonomic constraint.
    log = aidnav.simulate(ZOO / "short_car_pitch3_fixed.toml", as_frame=False)
    gnss = {k: v for k, v in log.gnss.items() if k not in ("has_velocity",)}
    config = {"platform": "car", "constraints": {"estimate_misalignment": True}}
    result = aidnav.process(config, imu=log.imu, gnss=gnss, score=False)
    install = result.install
    assert list(install["name"]) == ["misalignment_pitch", "misalignment_yaw"]
    assert list(install["unit"]) == ["rad", "rad"]
    pitch = np.degrees(install["value"][0])
    assert abs(pitch - log.installation["mounting_deg"][1]) < 0.2, pitch
    assert np.all(install["sigma"] < 0.5 * install["prior_sigma"])
