#!/usr/bin/env python3
"""Cut the fuzz targets' seed corpora (fuzz/corpus/<target>/seed-*) from the
recorded logs in data/ (or DATA=dir) and from the examples. Seeds
are small on purpose (a few kB): the fuzzer grows them."""
import math, os, pathlib, struct, sys

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

ex = top / "examples"
put("filter_measurements", "scalar", b"time,z1,z2\n0,1.0,2.0\n1,1.1,\n2,,2.2\n")
put("filter_model", "scalar", (ex / "01-scalar-filter/model.toml").read_bytes())
for f in sorted(ex.glob("*.toml")):
    target = "scenarios" if f.stem.startswith("formation") else "process_config"
    put(target, f.stem, f.read_bytes())
put("scenarios", "runs", b"runs = 10\nseed = 7\n")
print(f"seeds written under {corpus}")
