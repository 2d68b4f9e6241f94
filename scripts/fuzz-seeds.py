#!/usr/bin/env python3
"""Cut the fuzz targets' seed corpora (fuzz/corpus/<target>/seed-*) from the
recorded logs in data/ (or DATA=dir) and from the examples. Seeds
are small on purpose (a few kB): the fuzzer grows them."""
import datetime, math, os, pathlib, struct, sys

top = pathlib.Path(__file__).resolve().parent.parent
data = pathlib.Path(os.environ.get("DATA", top / "data/rtklibexplorer-gnss-imu"))
drive, walk = data / "drive_0708", data / "walk_0827"
corpus = top / "fuzz/corpus"


def put(target, name, payload):
    d = corpus / target
    d.mkdir(parents=True, exist_ok=True)
    (d / f"seed-{name}").write_bytes(payload)


def head(path, lines):
    with open(path, "rb") as f:
        return b"".join(f.readline() for _ in range(lines))


def nmea(body):
    c = 0
    for ch in body.encode():
        c ^= ch
    return f"${body}*{c:02X}\r\n"


for name, d, imu, pos in [("drive", drive, "imu_1934.csv", "gnss_1934_sf.pos"),
                          ("walk", walk, "imu_1730.csv", "gnss_1730_sf.pos")]:
    put("rtklib_pos", name, head(d / pos, 40))
    csv = head(d / imu, 40)
    tag = (d / (imu + ".tag")).read_bytes()[:64 + 12 * 8]
    put("rtklib_tagged_imu", name, struct.pack("<I", len(csv)) + csv + tag)
    # The same samples as the generic CSV and as KF-GINS increments (g, deg/s
    # in the raw file; 100 Hz).
    rows = [l.split(b",") for l in csv.splitlines() if l.count(b",") == 6]
    generic = ["time_s,gx_rad_s,gy_rad_s,gz_rad_s,ax_m_s2,ay_m_s2,az_m_s2"]
    kf = []
    for k, r in enumerate(rows):
        a = [float(v) * 9.80665 for v in r[0:3]]
        w = [math.radians(float(v)) for v in r[3:6]]
        t = 1_000.0 + 0.01 * k
        generic.append(",".join(f"{v:.6f}" for v in [t, *w, *a]))
        kf.append(" ".join(f"{v:.9f}" for v in [t, *(x * 0.01 for x in w), *(x * 0.01 for x in a)]))
    put("generic_imu", name, ("\n".join(generic) + "\n").encode())
    put("kfgins_imu", name, ("\n".join(kf) + "\n").encode())
    fixes = []
    for l in head(d / pos, 60).decode().splitlines():
        if l.startswith("%") or not l.strip():
            continue
        f = l.split()
        fixes.append(f)
        if len(fixes) == 12:
            break
    gnss = []
    for k, f in enumerate(fixes):
        lat, lon, h, sn, se, su = float(f[2]), float(f[3]), float(f[4]), float(f[7]), float(f[8]), float(f[9])
        gnss.append(f"{1000.0 + 0.25 * k:.3f} {lat:.9f} {lon:.9f} {h:.4f} {sn:.4f} {se:.4f} {su:.4f}")
    put("kfgins_gnss", name, ("\n".join(gnss) + "\n").encode())
    sentences = []
    for k, f in enumerate(fixes):
        lat, lon, h = float(f[2]), float(f[3]), float(f[4])
        hh, mm, ss = 19, 34, 1.0 + 0.25 * k
        t = f"{hh:02d}{mm:02d}{ss:05.2f}"
        la = f"{int(abs(lat)):02d}{(abs(lat) % 1) * 60:08.5f},{'N' if lat >= 0 else 'S'}"
        lo = f"{int(abs(lon)):03d}{(abs(lon) % 1) * 60:08.5f},{'E' if lon >= 0 else 'W'}"
        sentences.append(nmea(f"GNRMC,{t},A,{la},{lo},0.1,90.0,080725,,,D"))
        sentences.append(nmea(f"GNGGA,{t},{la},{lo},4,20,0.6,{h - 30.0:.3f},M,30.000,M,1.0,0000"))
        sentences.append(nmea(f"GNGST,{t},0.5,0.02,0.02,0.0,0.02,0.02,0.04"))
    put("nmea", name, "".join(sentences).encode())

# UBX: the walk's raw log as recorded (NMEA interleaved with NAV-PVT,
# RXM-RAWX and RXM-SFRBX frames), and its NAV-PVT frames alone around the
# change from RTK fixed to float (carrSoln 2 → 1).
ubx = (walk / "gnss_1730.ubx").read_bytes()
put("ubx", "walk-head", ubx[:8000])


def frames(data):
    i = 0
    while i + 8 <= len(data):
        if data[i] != 0xB5 or data[i + 1] != 0x62:
            i += 1
            continue
        n = struct.unpack_from("<H", data, i + 4)[0]
        yield data[i:i + 8 + n]
        i += 8 + n


pvt = [f for f in frames(ubx) if f[2:4] == b"\x01\x07"]
change = next(k for k, f in enumerate(pvt) if f[6 + 21] >> 6 == 1)
put("ubx", "walk-nav-pvt-fixed-to-float", b"".join(pvt[change - 6:change + 6]))


def gps_time(date, time):
    """GPST seconds since 1970 of a .pos time."""
    y, mo, d = (int(v) for v in date.split("/"))
    h, mi, s = time.split(":")
    days = (datetime.date(y, mo, d) - datetime.date(1970, 1, 1)).days
    return days * 86400 + int(h) * 3600 + int(mi) * 60 + float(s)


# Generic GNSS CSV: the first fixes of each .pos in three column forms.
for name, d, pos in [("drive", drive, "gnss_1934_sf.pos"), ("walk", walk, "gnss_1730_sf.pos")]:
    rows = [l.split() for l in head(d / pos, 40).decode().splitlines() if l.strip() and not l.startswith("%")][:12]
    geo = ["gpst_s,lat_deg,lon_deg,height_msl_m,geoid_sep_m,sigma_n_m,sigma_e_m,sigma_u_m,vel_n_mps,vel_e_mps,vel_d_mps,sigma_vel_mps,quality,satellites"]
    week = ["gps_week,tow_s,ecef_x_m,ecef_y_m,ecef_z_m,sigma_h_m,sigma_v_m,speed_mps,course_deg,vertical_speed_mps,quality"]
    utc = ["utc,lat_deg,lon_deg,height_m"]
    a, e2 = 6378137.0, 6.69437999014e-3
    for r in rows:
        t = gps_time(r[0], r[1])
        v = [float(x) for x in r[2:]]
        lat, lon, h = math.radians(v[0]), math.radians(v[1]), v[2] - 21.4
        n = a / math.sqrt(1 - e2 * math.sin(lat) ** 2)
        x = (n + h) * math.cos(lat) * math.cos(lon)
        y = (n + h) * math.cos(lat) * math.sin(lon)
        z = (n * (1 - e2) + h) * math.sin(lat)
        q = {1: "fixed", 2: "float", 5: "single"}.get(int(v[3]), str(int(v[3])))
        geo.append(f"{t:.3f},{v[0]:.7f},{v[1]:.7f},{v[2]:.3f},-21.400,{v[5]:.4f},{v[6]:.4f},{v[7]:.4f},{v[13]:.3f},{v[14]:.3f},{-v[15]:.3f},{v[16]:.3f},{int(v[3])},{int(v[4])}")
        w, tow = divmod(t - 315964800.0, 604800.0)
        speed, course = math.hypot(v[13], v[14]), math.degrees(math.atan2(v[14], v[13])) % 360.0
        week.append(f"{int(w)},{tow:.3f},{x:.4f},{y:.4f},{z:.4f},{v[5]:.4f},{v[7]:.4f},{speed:.3f},{course:.2f},{v[15]:.3f},{q}")
        u = datetime.datetime(1970, 1, 1) + datetime.timedelta(seconds=t - 18.0)
        utc.append(f"{u.isoformat(timespec='milliseconds')}Z,{v[0]:.7f},{v[1]:.7f},{h:.3f}")
    put("generic_gnss", f"{name}-geodetic", ("\n".join(geo) + "\n").encode())
    put("generic_gnss", f"{name}-week-ecef", ("\n".join(week) + "\n").encode())
    put("generic_gnss", f"{name}-utc-no-sigma", ("\n".join(utc) + "\n").encode())
    # Wheel speed and barometer CSVs from the same epochs: the ground speed
    # as the odometer's, the height (and its ISA pressure) as the
    # barometer's, in each column form.
    wheel_mps, wheel_kmh = ["gpst_s,speed_mps,sigma_mps"], ["gps_week,tow_s,speed_kmh"]
    baro_m, baro_hpa = ["utc,height_m,sigma_m"], ["time_s,pressure_hpa"]
    for k, r in enumerate(rows):
        t = gps_time(r[0], r[1])
        v = [float(x) for x in r[2:]]
        speed = math.hypot(v[13], v[14])
        w, tow = divmod(t - 315964800.0, 604800.0)
        wheel_mps.append(f"{t:.3f},{speed:.3f},{'0.05' if k % 3 else ''}")
        wheel_kmh.append(f"{int(w)},{tow:.3f},{speed * 3.6:.2f}")
        u = datetime.datetime(1970, 1, 1) + datetime.timedelta(seconds=t - 18.0)
        baro_m.append(f"{u.isoformat(timespec='milliseconds')}Z,{v[2] - 21.4:.2f},0.5")
        p = 1013.25 * (1 - 0.0065 * (v[2] - 21.4) / 288.15) ** 5.255876
        baro_hpa.append(f"{1000.0 + 0.25 * k:.2f},{p:.3f}")
    put("generic_wheel_speed", f"{name}-gpst", ("\n".join(wheel_mps) + "\n").encode())
    put("generic_wheel_speed", f"{name}-week-kmh", ("\n".join(wheel_kmh) + "\n").encode())
    put("generic_baro", f"{name}-utc-height", ("\n".join(baro_m) + "\n").encode())
    put("generic_baro", f"{name}-pressure", ("\n".join(baro_hpa) + "\n").encode())

ex = top / "examples"
put("generic_gnss", "example", (ex / "data/gnss_generic_example.csv").read_bytes())
put("filter_measurements", "scalar", b"time,z1,z2\n0,1.0,2.0\n1,1.1,\n2,,2.2\n")
put("filter_model", "scalar", (ex / "01-scalar-filter/model.toml").read_bytes())
for f in sorted(ex.glob("*.toml")):
    target = "scenarios" if f.stem.startswith("formation") else "process_config"
    put(target, f.stem, f.read_bytes())
put("scenarios", "runs", b"runs = 10\nseed = 7\n")
print(f"seeds written under {corpus}")
