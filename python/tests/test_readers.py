"""The readers: every format process reads, their columns, their errors
(the same messages as the CLI's)."""

import subprocess

import numpy as np
import pytest

import aidnav

from conftest import DRIVE_DATA, ROOT

WALK = ROOT / "data" / "rtklibexplorer-gnss-imu" / "walk_0827"


def as_dict(t):
    return {k: np.asarray(t[k]) for k in t} if not isinstance(t, dict) else t


def test_rtklib_files_of_the_drive():
    imu = as_dict(aidnav.read_imu(DRIVE_DATA / "imu_1934.csv", "rtklib_tagged", tags=DRIVE_DATA / "imu_1934.csv.tag"))
    gnss = as_dict(aidnav.read_gnss(DRIVE_DATA / "gnss_1934_sf.pos", "rtklib_pos"))
    assert list(imu) == ["time_s", "gx_rad_s", "gy_rad_s", "gz_rad_s", "ax_m_s2", "ay_m_s2", "az_m_s2"]
    assert len(imu["time_s"]) > 50_000 and np.all(np.diff(imu["time_s"]) > 0)
    # At rest the specific force is about one g.
    g = np.median(np.linalg.norm(np.c_[imu["ax_m_s2"], imu["ay_m_s2"], imu["az_m_s2"]], axis=1))
    assert 9.6 < g < 10.0
    assert len(gnss["gpst_s"]) == 2197
    assert np.all(np.abs(gnss["lat_deg"]) <= 90) and np.all(gnss["sigma_n_m"] > 0)
    assert set(np.unique(gnss["quality"])) <= {1, 2, 5}


def test_ubx_of_the_walk_and_the_generic_example():
    gnss = as_dict(aidnav.read_gnss(WALK / "gnss_1730.ubx", "ubx"))
    assert len(gnss["gpst_s"]) > 100 and gnss["has_velocity"].all()
    assert np.isfinite(gnss["vel_n_mps"]).all()
    ex = as_dict(aidnav.read_gnss(ROOT / "examples" / "data" / "gnss_generic_example.csv", "generic_csv"))
    assert len(ex["gpst_s"]) > 0


def test_generic_kf_gins_and_nmea_written_here(tmp_path):
    t = 1_752_003_258.0 + np.arange(5) * 0.01
    imu = tmp_path / "imu.csv"
    imu.write_text("time_s,gx_rad_s,gy_rad_s,gz_rad_s,ax_m_s2,ay_m_s2,az_m_s2\n" + "".join(f"{x:.2f},0,0,0.01,0.1,0,-9.8\n" for x in t))
    got = as_dict(aidnav.read_imu(imu, "generic_csv"))
    np.testing.assert_array_equal(got["gz_rad_s"], np.full(5, 0.01))
    deg = tmp_path / "imu_deg.csv"
    deg.write_text("time_s,gx,gy,gz,ax,ay,az\n" + "".join(f"{x:.2f},0,0,1.0,0,0,-1\n" for x in t))
    got = as_dict(aidnav.read_imu(deg, "generic_csv", units={"gyro": "deg_s", "accel": "g"}))
    np.testing.assert_allclose(got["gz_rad_s"], np.radians(1.0))
    np.testing.assert_allclose(got["az_m_s2"], -9.80665)
    kf = tmp_path / "imu.txt"
    kf.write_text("".join(f"{x:.2f} 0 0 1e-4 0.001 0 -0.098\n" for x in t))
    got = as_dict(aidnav.read_imu(kf, "kf_gins"))
    assert len(got["time_s"]) >= 4
    g = tmp_path / "gnss.txt"
    g.write_text("".join(f"{x:.2f} 30.5 114.3 20.0 0.02 0.02 0.05\n" for x in t))
    got = as_dict(aidnav.read_gnss(g, "kf_gins"))
    np.testing.assert_allclose(got["lat_deg"], 30.5)
    nmea = tmp_path / "g.nmea"
    nmea.write_text(
        nmea_sentence("GPRMC,193418.00,A,3733.00000,N,12200.00000,W,0.0,0.0,080725,,,D")
        + nmea_sentence("GPGGA,193418.00,3733.00000,N,12200.00000,W,4,12,0.8,10.0,M,-30.0,M,,")
    )
    got = as_dict(aidnav.read_gnss(nmea, "nmea"))
    np.testing.assert_allclose(got["lat_deg"], 37.55)
    np.testing.assert_allclose(got["lon_deg"], -122.0)
    np.testing.assert_allclose(got["height_m"], -20.0)  # MSL 10 m + geoid separation -30 m
    broken = tmp_path / "b.nmea"
    broken.write_text("$GPGGA,193418.00,3733.00000,N*00\n")
    with pytest.raises(aidnav.DataError, match=f"{broken}:1: column `checksum`"):
        aidnav.read_gnss(broken, "nmea")


def nmea_sentence(body):
    checksum = 0
    for c in body:
        checksum ^= ord(c)
    return f"${body}*{checksum:02X}\n"


def test_errors_name_file_line_column_as_the_cli_does(tmp_path, cli_exe):
    bad = tmp_path / "imu.csv"
    bad.write_text("time_s,gx_rad_s,gy_rad_s,gz_rad_s,ax_m_s2,ay_m_s2,az_m_s2\n1.0,0,0,0,0,0,-9.8\n1.01,0,zero,0,0,0,-9.8\n")
    with pytest.raises(aidnav.DataError) as err:
        aidnav.read_imu(bad, "generic_csv")
    message = str(err.value)
    assert message.startswith(f"{bad}:3: column `gy_rad_s`: "), message
    # The CLI refuses the same file with the same words.
    cfg = tmp_path / "c.toml"
    cfg.write_text(f'[data]\ndir = "{tmp_path}"\nimu = "imu.csv"\nimu_format = "generic_csv"\ngnss = "g.pos"\n')
    done = subprocess.run([cli_exe, "process", str(cfg), "--out", str(tmp_path / "o")], capture_output=True, text=True)
    assert done.returncode != 0 and message in done.stderr, done.stderr
    with pytest.raises(aidnav.DataError, match="cannot read"):
        aidnav.read_gnss(tmp_path / "missing.pos")
    with pytest.raises(ValueError, match="unknown variant `csv`"):
        aidnav.read_gnss(bad, "csv")
    with pytest.raises(aidnav.DataError, match="imu_tags is needed"):
        aidnav.read_imu(bad, "rtklib_tagged")

