"""`process` from Python against the CLI on the drive example."""

import filecmp
import json

import numpy as np
import pytest

import aidnav

from conftest import DRIVE, DRIVE_DATA

#: Keys of `summary.json`'s result that depend on the run, not on the numbers.
VOLATILE = {"timing_s", "files"}


def test_same_summary_as_the_cli(drive_cli, drive_py):
    cli = json.loads((drive_cli / "summary.json").read_text())
    ours = drive_py.summary
    assert {k: v for k, v in ours.items() if k != "result"} == {k: v for k, v in cli.items() if k != "result"}
    strip = lambda r: {k: v for k, v in r.items() if k not in VOLATILE}  # noqa: E731
    assert strip(ours["result"]) == strip(cli["result"])
    # Real numbers, not empty tables: the drive tracks to centimetres and
    # coasts 10 s outages to metres (README, spec 40 results).
    assert 0.0 < ours["result"]["tracking_rms_m"] < 0.05
    assert len(ours["result"]["outages"]) == 3
    # Every measurement stream is counted; the drive has no wheel-speed or
    # barometer table, so their per-update tables are empty.
    names = [s["name"] for s in ours["result"]["aid_sources"]]
    assert names == ["non_holonomic", "zero_velocity", "zero_angular_rate", "gnss_position", "gnss_velocity"]
    assert len(np.asarray(drive_py.wheel_speed["nis"])) == 0
    assert len(np.asarray(drive_py.barometer["innovation [m]"])) == 0


def test_tables_hold_the_files_columns(drive_cli, drive_py, tmp_path):
    sol = drive_py.solution
    csv = np.genfromtxt(drive_cli / "solution.csv", delimiter=",", skip_header=1)
    assert list(sol.keys())[0] == "time [s GPST since 1970]"
    got = np.column_stack([np.asarray(sol[k]) for k in sol])
    # The CSV prints shortest round-trip decimals: equal to the bit.
    np.testing.assert_array_equal(np.isnan(got), np.isnan(csv))
    np.testing.assert_array_equal(got[~np.isnan(got)], csv[~np.isnan(csv)])
    scores = drive_py.scores
    filt = [i for i, s in enumerate(np.asarray(scores["solution"])) if s == "filter"]
    assert np.asarray(scores["outage_s"])[filt].tolist() == [10.0, 30.0, 60.0]
    # write() writes the CLI's files, the tables byte for byte.
    files = drive_py.write(tmp_path / "out")
    names = sorted(p.split("/")[-1] for p in files)
    assert names == sorted(p.name for p in drive_cli.iterdir())
    for name in ("solution.csv", "smoothed.csv", "instruments.csv"):
        assert filecmp.cmp(tmp_path / "out" / name, drive_cli / name, shallow=False), name


def test_in_memory_arrays_give_the_files_result(drive_py):
    imu = aidnav.read_imu(DRIVE_DATA / "imu_1934.csv", "rtklib_tagged", tags=DRIVE_DATA / "imu_1934.csv.tag")
    gnss = aidnav.read_gnss(DRIVE_DATA / "gnss_1934_sf.pos", "rtklib_pos")
    mem = aidnav.process(DRIVE, imu=imu, gnss=gnss, score=False)
    a, b = mem.result, drive_py.result
    # Latitude and longitude travel in degrees: rad → deg → rad moves them
    # by an ULP or so (1e-16 rad ≈ 1 nm), which the filter carries on.
    assert a["tracking_rms_m"] == pytest.approx(b["tracking_rms_m"], rel=1e-6)
    assert a["outcomes"] == b["outcomes"]
    np.testing.assert_allclose(np.asarray(mem.solution["nis"]), np.asarray(drive_py.solution["nis"]), rtol=1e-5, atol=1e-6)
    assert not mem.scored and len(mem.result["outages"]) == 0


DATA = {"dir": ".", "imu": "i.csv", "imu_format": "generic_csv", "gnss": "g.csv", "gnss_format": "generic_csv"}


def test_a_config_dict_is_checked_as_a_file_is(tmp_path):
    with pytest.raises(aidnav.ConfigError) as err:
        aidnav.process({"data": DATA, "imu": {"smoothing_s": -1.0}})
    assert "<config dict>:" in str(err.value) and "imu.smoothing_s" in str(err.value)
    # The scheme keys of [gnss] are the engine's, with its ranges.
    with pytest.raises(aidnav.ConfigError, match=r"gnss\.huber_k: 0 is out of range: allowed 0\.1 ≤ huber_k ≤ 100"):
        aidnav.process({"data": DATA, "gnss": {"huber_k": 0.0}})
    with pytest.raises(aidnav.ConfigError, match=r"gnss\.chi2_probability: 1 is out of range"):
        aidnav.process({"data": DATA, "gnss": {"chi2_probability": 1.0}})
    with pytest.raises(aidnav.ConfigError, match="unknown field `colour`"):
        aidnav.process({"data": DATA, "colour": 1})
    with pytest.raises(aidnav.DataError, match="cannot read"):
        aidnav.process({"data": {"dir": str(tmp_path), "imu": "i.csv", "imu_format": "generic_csv", "gnss": "g.pos"}})
    # In-memory columns are checked too, naming the column and the row.
    imu = {"time_s": np.arange(3.0), "gx_rad_s": [0, np.nan, 0], "gy_rad_s": np.zeros(3), "gz_rad_s": np.zeros(3),
           "ax_m_s2": np.zeros(3), "ay_m_s2": np.zeros(3), "az_m_s2": np.zeros(3)}
    gnss = {"gpst_s": [0.0], "lat_deg": [45.0], "lon_deg": [7.0], "height_m": [100.0],
            "sigma_n_m": [1.0], "sigma_e_m": [1.0], "sigma_u_m": [2.0]}
    with pytest.raises(aidnav.DataError, match=r"imu \(in memory\): row 1: column `gx_rad_s`"):
        aidnav.process({"initial": {"attitude_deg": [0.0, 0.0, 0.0]}}, imu=imu, gnss=gnss)


def test_a_config_dict_with_arrays_runs(drive_py):
    # The synthetic log of the library's doc example: at rest, attitude given.
    g = 9.80
    n = 1200
    imu = {"time_s": np.arange(n) * 0.01, "gx_rad_s": np.zeros(n), "gy_rad_s": np.zeros(n), "gz_rad_s": np.zeros(n),
           "ax_m_s2": np.zeros(n), "ay_m_s2": np.zeros(n), "az_m_s2": np.full(n, -g)}
    k = np.arange(48)
    gnss = {"gpst_s": k * 0.25, "lat_deg": np.full(48, 34.4), "lon_deg": np.full(48, 11.5), "height_m": np.full(48, 10.0),
            "sigma_n_m": np.full(48, 0.02), "sigma_e_m": np.full(48, 0.02), "sigma_u_m": np.full(48, 0.02),
            "quality": np.ones(48, dtype=int)}
    r = aidnav.process({"initial": {"attitude_deg": [0.0, 0.0, 0.0]}, "outage_bridge": {"enabled": False}},
                       imu=imu, gnss=gnss, score=False)
    assert r.result["gnss_epochs"] == 48
    assert r.result["tracking_rms_m"] < 0.05
