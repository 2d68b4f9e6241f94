use super::*;

fn read(text: &str) -> Result<(Vec<GnssFix>, Vec<String>)> {
    read_generic_gnss_from(
        text.as_bytes(),
        Path::new("g.csv"),
        GenericGnssOptions::default(),
    )
}

fn read_with(text: &str, sigma: [f64; 2]) -> Result<(Vec<GnssFix>, Vec<String>)> {
    read_generic_gnss_from(
        text.as_bytes(),
        Path::new("g.csv"),
        GenericGnssOptions {
            default_sigma_m: Some(sigma),
        },
    )
}

fn err(text: &str) -> String {
    read(text).unwrap_err().to_string()
}

/// 2025-08-28 17:30:39.75 GPST (17:30:21.75 UTC): GPS week 2381.
const GPST: f64 = 315_964_800.0 + 2381.0 * 604_800.0 + 408_639.75;

const POS: &str = "40.0966916,-105.1471665,1580.048";

#[test]
fn the_three_time_forms_agree() {
    let tail = format!("{POS},0.01,0.01,0.02");
    let rest = "lat_deg,lon_deg,height_m,sigma_n_m,sigma_e_m,sigma_u_m";
    for (time_header, time) in [
        ("gpst_s", "1756402239.75".to_string()),
        ("gps_week,tow_s", "2381,408639.75".to_string()),
        ("utc", "2025-08-28T17:30:21.75Z".to_string()),
        ("utc", "2025-08-28 17:30:21.750".to_string()),
        ("utc", "2025-08-28T19:30:21.75+02:00".to_string()),
        ("utc", "2025-08-28T12:30:21.75-0500".to_string()),
    ] {
        let (f, w) = read(&format!("{time_header},{rest}\n{time},{tail}\n")).unwrap();
        assert!(w.is_empty(), "{w:?}");
        assert!(
            (f[0].time_s - GPST).abs() < 1e-6,
            "{time}: {}",
            f[0].time_s - GPST
        );
    }
    // The leap seconds of the UTC date: 17 s on 2016-12-31, 18 s after.
    let (f, _) = read(&format!(
        "utc,{rest}\n2016-12-31T23:59:59Z,{tail}\n2016-12-31T23:59:60.5Z,{tail}\n2017-01-01T00:00:00Z,{tail}\n"
    ))
    .unwrap();
    let day = days_from_civil(2017, 1, 1) as f64 * 86_400.0;
    assert_eq!(
        f.iter().map(|f| f.time_s - day).collect::<Vec<_>>(),
        [16.0, 17.5, 18.0]
    );
}

#[test]
fn the_three_position_forms_agree() {
    let p = Geodetic {
        latitude_rad: 40.0966916f64.to_radians(),
        longitude_rad: (-105.1471665f64).to_radians(),
        height_m: 1580.048,
    };
    let r = p.to_ecef();
    let sig = "0.01,0.01,0.02";
    let s = "sigma_n_m,sigma_e_m,sigma_u_m";
    for text in [
        format!("gpst_s,lat_deg,lon_deg,height_m,{s}\n{GPST},{POS},{sig}\n"),
        format!(
            "gpst_s,lat_deg,lon_deg,height_msl_m,geoid_sep_m,{s}\n{GPST},40.0966916,-105.1471665,1601.435,-21.387,{sig}\n"
        ),
        format!(
            "gpst_s,ecef_x_m,ecef_y_m,ecef_z_m,{s}\n{GPST},{:.4},{:.4},{:.4},{sig}\n",
            r.x(),
            r.y(),
            r.z()
        ),
    ] {
        let (f, _) = read(&text).unwrap();
        let d = p.ned_to(&f[0].position).norm();
        assert!(d < 1e-4, "{d} m from\n{text}");
    }
}

#[test]
fn sigma_comes_from_columns_or_the_configuration() {
    let (f, _) = read(&format!(
        "gpst_s,lat_deg,lon_deg,height_m,sigma_n_m,sigma_e_m,sigma_u_m\n{GPST},{POS},0.011,0.012,0.03\n"
    ))
    .unwrap();
    assert_eq!(f[0].position_sigma_neu, Vector3::new(0.011, 0.012, 0.03));
    let (f, _) = read(&format!(
        "gpst_s,lat_deg,lon_deg,height_m,sigma_h_m,sigma_v_m\n{GPST},{POS},0.5,0.9\n"
    ))
    .unwrap();
    assert_eq!(f[0].position_sigma_neu, Vector3::new(0.5, 0.5, 0.9));
    let bare = format!("gpst_s,lat_deg,lon_deg,height_m\n{GPST},{POS}\n");
    let (f, _) = read_with(&bare, [2.0, 4.0]).unwrap();
    assert_eq!(f[0].position_sigma_neu, Vector3::new(2.0, 2.0, 4.0));
    let e = err(&bare);
    assert!(
        e.starts_with("g.csv:1: column `(σ)`: no position σ") && e.contains("[data] gnss_sigma_m"),
        "{e}"
    );
    // Columns win over the configuration.
    let (f, _) = read_with(
        &format!("gpst_s,lat_deg,lon_deg,height_m,sigma_h_m,sigma_v_m\n{GPST},{POS},0.5,0.9\n"),
        [2.0, 4.0],
    )
    .unwrap();
    assert_eq!(f[0].position_sigma_neu.x, 0.5);
}

#[test]
fn velocity_as_ned_or_speed_and_course() {
    let head = "gpst_s,lat_deg,lon_deg,height_m,sigma_h_m,sigma_v_m";
    let (ned, w) = read(&format!(
        "{head},vel_n_mps,vel_e_mps,vel_d_mps,sigma_vel_mps\n{GPST},{POS},0.1,0.2,-1.0,1.0,0.05,0.1\n{},{POS},0.1,0.2,,,,\n",
        GPST + 1.0
    ))
    .unwrap();
    assert!(w.is_empty(), "{w:?}");
    assert_eq!(ned[0].velocity_ned, Some(Vector3::new(-1.0, 1.0, 0.05)));
    assert_eq!(ned[0].velocity_sigma_neu, Some(Vector3::repeat(0.1)));
    // An empty velocity: none that epoch.
    assert_eq!(
        (ned[1].velocity_ned, ned[1].velocity_sigma_neu),
        (None, None)
    );
    // 2 m/s towards 135° (south-east), climbing 0.5 m/s.
    let (sc, w) = read(&format!(
        "{head},speed_mps,course_deg,vertical_speed_mps\n{GPST},{POS},0.1,0.2,2.0,135,0.5\n"
    ))
    .unwrap();
    let v = sc[0].velocity_ned.unwrap();
    let h = 2f64.sqrt();
    assert!((v - Vector3::new(-h, h, -0.5)).norm() < 1e-12, "{v}");
    assert_eq!(sc[0].velocity_sigma_neu, Some(Vector3::repeat(0.1)));
    assert_eq!(
        w,
        ["g.csv: 1 epochs with velocity but no sigma_vel_mps: 0.1 m/s assumed on each axis"]
    );
    // Without the vertical speed: 0, unobserved.
    let (sc, w) = read(&format!(
        "{head},speed_mps,course_deg,sigma_vel_mps\n{GPST},{POS},0.1,0.2,2.0,90,0.3\n"
    ))
    .unwrap();
    assert_eq!(sc[0].velocity_sigma_neu, Some(Vector3::new(0.3, 0.3, 10.0)));
    assert!(w[0].contains("no vertical_speed_mps"), "{w:?}");
    // Part of a velocity: an error naming the empty cell.
    let e = err(&format!(
        "{head},vel_n_mps,vel_e_mps,vel_d_mps\n{GPST},{POS},0.1,0.2,1.0,,0.0\n"
    ));
    assert_eq!(e, "g.csv:2: column `vel_e_mps`: empty: a value is needed");
}

#[test]
fn quality_words_and_numbers() {
    let head = "gpst_s,lat_deg,lon_deg,height_m,sigma_h_m,sigma_v_m,quality,satellites";
    let rows: String = ["fixed", "Float", "dgps", "single", "1", "6", ""]
        .iter()
        .enumerate()
        .map(|(k, q)| format!("{},{POS},0.1,0.2,{q},{k}\n", GPST + k as f64))
        .collect();
    let (f, _) = read(&format!("{head}\n{rows}")).unwrap();
    assert_eq!(
        f.iter()
            .map(|f| (f.quality, f.satellites))
            .collect::<Vec<_>>(),
        [(1, 0), (2, 1), (4, 2), (5, 3), (1, 4), (6, 5), (0, 6)]
    );
    let e = err(&format!("{head}\n{GPST},{POS},0.1,0.2,rtk,12\n"));
    assert!(
        e.starts_with("g.csv:2: column `quality`: `rtk` is no quality"),
        "{e}"
    );
    let e = err(&format!("{head}\n{GPST},{POS},0.1,0.2,1,12.5\n"));
    assert!(
        e.starts_with("g.csv:2: column `satellites`: 12.5 is not a whole"),
        "{e}"
    );
}

#[test]
fn header_mistakes_name_the_columns() {
    let e = err(&format!(
        "gpst_s,lat_deg,lon_deg,height_m,hdop\n{GPST},{POS},1\n"
    ));
    assert!(
        e.starts_with("g.csv:1: column `hdop`: unknown column (column 5); the known columns are: gpst_s, gps_week, tow_s, utc, lat_deg"),
        "{e}"
    );
    let e = err(&format!(
        "gpst_s,lat_deg,lon_deg,height_m,\n{GPST},{POS},\n"
    ));
    assert!(
        e.contains("unknown column with an empty name (a trailing comma?) (column 5)"),
        "{e}"
    );
    let e = err("gps_week,lat_deg,lon_deg,height_m\n2381,40,-105,1580\n");
    assert_eq!(
        e,
        "g.csv:1: column `tow_s`: column missing: GPS week time needs gps_week, tow_s (missing: tow_s)"
    );
    let e = err("gpst_s,lat_deg,height_m\n1e9,40,1580\n");
    assert!(
        e.starts_with("g.csv:1: column `lon_deg`: column missing"),
        "{e}"
    );
    let e = err("gpst_s,lat_deg,lon_deg\n1e9,40,-105\n");
    assert!(
        e.starts_with("g.csv:1: column `height_m`: column missing"),
        "{e}"
    );
    let e = err("gpst_s,utc,lat_deg,lon_deg,height_m\n");
    assert!(e.contains("the time given twice (gpst_s and utc)"), "{e}");
    let e = err("gpst_s,lat_deg,lon_deg,height_m,height_msl_m,geoid_sep_m\n");
    assert!(e.contains("the height given twice"), "{e}");
    let e = err("gpst_s,lat_deg,lat_deg\n");
    assert_eq!(e, "g.csv:1: column `lat_deg`: named twice (column 3)");
    let e = err("lat_deg,lon_deg,height_m\n40,-105,1580\n");
    assert!(
        e.starts_with("g.csv:1: column `(time)`: no time column"),
        "{e}"
    );
    let e = err("gpst_s,sigma_h_m,sigma_v_m\n1e9,1,1\n");
    assert!(
        e.starts_with("g.csv:1: column `(position)`: no position columns"),
        "{e}"
    );
    let e = err("gpst_s,ecef_x_m,ecef_y_m,ecef_z_m,height_m\n");
    assert!(e.contains("an ECEF position takes no height column"), "{e}");
    let e = err("gpst_s,lat_deg,lon_deg,height_m,sigma_h_m,sigma_v_m,sigma_vel_mps\n");
    assert!(
        e.starts_with("g.csv:1: column `sigma_vel_mps`: a velocity σ without"),
        "{e}"
    );
    let e = err("# only a comment\n\n");
    assert!(
        e.starts_with("g.csv:0: column `(header)`: no header row"),
        "{e}"
    );
    let e = err("gpst_s,lat_deg,lon_deg,height_m,sigma_h_m,sigma_v_m\n");
    assert!(e.contains("no data rows"), "{e}");
}

#[test]
fn bad_values_name_file_line_and_column() {
    let head = "gpst_s,lat_deg,lon_deg,height_m,sigma_h_m,sigma_v_m,speed_mps,course_deg";
    let ok = format!("{GPST},{POS},0.1,0.2,1.0,90");
    let next = |cells: &str| format!("{head}\n{ok}\n{},{cells}\n", GPST + 1.0);
    for (cells, want) in [
        (
            "91,-105,1580,0.1,0.2,1,90",
            "column `lat_deg`: 91 deg is outside [-90, 90] deg",
        ),
        (
            "40,-105,150000,0.1,0.2,1,90",
            "column `height_m`: 150000 m is outside [-1000, 100000] m",
        ),
        (
            "40,-105,1580,0,0.2,1,90",
            "column `sigma_h_m`: σ = 0 m: must be > 0",
        ),
        ("40,-105,1580,0.1,-1,1,90", "column `sigma_v_m`: σ = -1 m"),
        (
            "40,-105,1580,0.1,NaN,1,90",
            "column `sigma_v_m`: `NaN` is not finite",
        ),
        (
            "40,-105,1580,0.1,0.2,1500,90",
            "column `speed_mps`: 1500 m/s is outside [0, 1000] m/s",
        ),
        (
            "40,-105,1580,0.1,0.2,1,abc",
            "column `course_deg`: `abc` is not a number",
        ),
        (
            "40,-105,1580,0.1,0.2,1",
            "column `(line)`: 7 cells, the header (line 1) has 8",
        ),
    ] {
        let e = err(&format!("{}{ok}\n", next(cells)));
        assert!(e.starts_with(&format!("g.csv:3: {want}")), "{want}\n{e}");
    }
    // Time: seconds of week as gpst_s, a week's end, a date, order.
    let e = err(&format!("{head}\n408639.75,{POS},0.1,0.2,1,90\n"));
    assert!(
        e.starts_with("g.csv:2: column `gpst_s`: 408639.75 s is outside [315964800, "),
        "{e}"
    );
    let e = err(&format!(
        "gps_week,tow_s,lat_deg,lon_deg,height_m,sigma_h_m,sigma_v_m\n2381,604800,{POS},0.1,0.2\n"
    ));
    assert!(
        e.starts_with("g.csv:2: column `tow_s`: 604800 s is outside a week"),
        "{e}"
    );
    let e = err(&format!(
        "utc,lat_deg,lon_deg,height_m,sigma_h_m,sigma_v_m\n2025-02-29T00:00:00Z,{POS},0.1,0.2\n"
    ));
    assert!(
        e.starts_with("g.csv:2: column `utc`: `2025-02-29` is not a calendar date"),
        "{e}"
    );
    for bad in [
        "2025-08-28",
        "2025-08-28T17:30:21.Z",
        "2025-8-28T17:30:21Z",
        "2025-08-28T17:30:21+2:00",
        "28/08/2025 17:30:21",
    ] {
        let e = err(&format!(
            "utc,lat_deg,lon_deg,height_m,sigma_h_m,sigma_v_m\n{bad},{POS},0.1,0.2\n"
        ));
        assert!(e.contains("is not an ISO 8601 time"), "{bad}: {e}");
    }
    let e = err(&format!("{head}\n{ok}\n{ok}\n"));
    assert!(
        e.starts_with(
            "g.csv:3: column `gpst_s`: time 2025-08-28 17:30:39.750 GPST does not increase"
        ),
        "{e}"
    );
    // Geoid separation and a point inside the Earth.
    let e = err(&format!(
        "gpst_s,lat_deg,lon_deg,height_msl_m,geoid_sep_m,sigma_h_m,sigma_v_m\n{GPST},40,-105,1601,-300,0.1,0.2\n"
    ));
    assert!(
        e.starts_with("g.csv:2: column `geoid_sep_m`: -300 m is outside [-200, 200] m"),
        "{e}"
    );
    let e = err(&format!(
        "gpst_s,ecef_x_m,ecef_y_m,ecef_z_m,sigma_h_m,sigma_v_m\n{GPST},1000,2000,3000,0.1,0.2\n"
    ));
    assert!(
        e.starts_with("g.csv:2: column `ecef_x_m`: the point's ellipsoidal height"),
        "{e}"
    );
}

#[test]
fn bom_comments_cr_and_a_truncated_last_line() {
    let text = format!(
        "\u{FEFF}# exported by a receiver\r\ngpst_s,lat_deg,lon_deg,height_m,sigma_h_m,sigma_v_m\r\n# a comment\r\n{GPST},{POS},0.1,0.2\r\n\r\n{},{POS},0.1,0.2\r{},40.09",
        GPST + 1.0,
        GPST + 2.0
    );
    let (f, w) = read(&text).unwrap();
    assert_eq!(f.len(), 2);
    assert_eq!(w, ["g.csv:7: truncated last line skipped (2 of 6 cells)"]);
}

#[test]
fn long_values_stay_short_in_messages() {
    let long = "9".repeat(5000);
    let e = err(&format!(
        "gpst_s,lat_deg,lon_deg,height_m,sigma_h_m,sigma_v_m\n{GPST},x{long},-105,1580,0.1,0.2\n"
    ));
    assert!(e.len() < 200 && e.contains('…'), "{e}");
    let e = err(&format!("{long}\n"));
    assert!(e.len() < 1000, "{} chars", e.len());
}

#[test]
fn the_example_file_reads() {
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/data/gnss_generic_example.csv");
    let (f, w) = read_generic_gnss(&path, GenericGnssOptions::default()).unwrap();
    assert!(f.len() >= 8, "{}", f.len());
    assert!(w.is_empty(), "{w:?}");
    assert!(f.iter().all(|f| f.velocity_ned.is_some() && f.quality == 1));
}
