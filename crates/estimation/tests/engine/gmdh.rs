//! GMDH model selection: recovers a known structure, refuses to invent one in noise.

use aidnav_estimation::gmdh::{FrequencyGrid, GmdhConfig, Split, Unit, select};

use crate::common::{normal, rng};

fn grid() -> FrequencyGrid {
    // 2π/400 … 2π/10 rad/s, 40 log-spaced points.
    let two_pi = 2.0 * std::f64::consts::PI;
    FrequencyGrid {
        min: two_pi / 400.0,
        max: two_pi / 10.0,
        count: 40,
    }
}

#[test]
fn recovers_trend_plus_sinusoid_from_noisy_samples() {
    let two_pi = 2.0 * std::f64::consts::PI;
    let omega = two_pi / 60.0;
    for seed in 17..22 {
        let mut g = rng(seed);
        let t: Vec<f64> = (0..400).map(|k| k as f64).collect();
        let truth = |t: f64| 1.0 - 0.004 * t + 1.5 * (omega * t + 0.3).sin();
        let y: Vec<f64> = t.iter().map(|&t| truth(t) + 0.1 * normal(&mut g)).collect();
        let config = GmdhConfig {
            search: Some(grid()),
            ..GmdhConfig::default()
        };
        let sel = select(&t, &y, &config).unwrap();
        let units = &sel.model.units;
        assert!(
            units.contains(&Unit::Power { p: 0 }) && units.contains(&Unit::Power { p: 1 }),
            "{units:?}"
        );
        let harmonics: Vec<f64> = units
            .iter()
            .filter_map(|u| {
                if let Unit::Harmonic { omega } = u {
                    Some(*omega)
                } else {
                    None
                }
            })
            .collect();
        assert_eq!(harmonics.len(), 1, "{units:?}");
        // Refined from the grid (ratio 40^(1/39) ≈ 1.099) to within 0.5 %.
        assert!(
            (harmonics[0] / omega - 1.0).abs() < 0.005,
            "ω = {} vs {omega}",
            harmonics[0]
        );
        assert!(units.len() <= 3, "over-complex: {units:?}");
        // Inside the window the model follows the truth to about the noise level.
        let rms = (t
            .iter()
            .map(|&t| (sel.model.predict(t) - truth(t)).powi(2))
            .sum::<f64>()
            / t.len() as f64)
            .sqrt();
        assert!(rms < 0.3, "rms {rms}");
    }
}

#[test]
fn given_frequency_and_exact_data_extrapolate_exactly() {
    let omega = 2.0 * std::f64::consts::PI / 84.4;
    let t: Vec<f64> = (0..120).map(|k| k as f64 * 0.5).collect();
    let y: Vec<f64> = t
        .iter()
        .map(|&t| 0.2 * (omega * t).sin() - 0.1 * (omega * t).cos())
        .collect();
    let config = GmdhConfig {
        frequencies: vec![omega],
        split: Split::Latest { fraction: 0.3 },
        ..GmdhConfig::default()
    };
    let sel = select(&t, &y, &config).unwrap();
    assert_eq!(sel.model.units, vec![Unit::Harmonic { omega }]);
    let t_future = 100.0;
    let expect = 0.2 * (omega * t_future).sin() - 0.1 * (omega * t_future).cos();
    assert!((sel.model.predict(t_future) - expect).abs() < 1e-9);
}

#[test]
fn does_not_pick_an_over_complex_structure_on_pure_noise() {
    let config = GmdhConfig {
        search: Some(grid()),
        ..GmdhConfig::default()
    };
    for seed in 0..10 {
        let mut g = rng(100 + seed);
        let t: Vec<f64> = (0..300).map(|k| k as f64).collect();
        let y: Vec<f64> = t.iter().map(|_| 0.5 + normal(&mut g)).collect();
        let sel = select(&t, &y, &config).unwrap();
        assert_eq!(
            sel.model.units,
            vec![Unit::Power { p: 0 }],
            "seed {seed}: {:?}",
            sel.model.units
        );
        assert!((sel.model.coefficients[0] - 0.5).abs() < 0.2);
    }
}

#[test]
fn bad_input_is_an_error() {
    let c = GmdhConfig::default();
    assert!(select(&[0.0, 1.0], &[1.0], &c).is_err());
    assert!(select(&[0.0, 1.0, 2.0], &[1.0, 2.0, 3.0], &c).is_err());
    let t: Vec<f64> = (0..10).map(f64::from).collect();
    let mut y = vec![1.0; 10];
    y[3] = f64::NAN;
    assert!(
        select(&t, &y, &c)
            .unwrap_err()
            .to_string()
            .contains("sample 3")
    );
    let mut t2 = t.clone();
    t2[5] = 4.0;
    assert!(
        select(&t2, &[1.0; 10], &c)
            .unwrap_err()
            .to_string()
            .contains("time 5")
    );
}

/// A linear trend under correlated (AR(1), 100 s) noise — the shape of a
/// filter's error history before an outage. Returns (t, y, trend).
fn trend_under_correlated_noise(seed: u64) -> (Vec<f64>, Vec<f64>, impl Fn(f64) -> f64) {
    let mut g = rng(seed);
    let a: f64 = (-5.0_f64 / 100.0).exp();
    let mut ar = 0.0;
    let t: Vec<f64> = (0..200).map(|k| 5.0 * k as f64).collect();
    let trend = |t: f64| 0.3 + 0.002 * t;
    let y: Vec<f64> = t
        .iter()
        .map(|&t| {
            ar = a * ar + 0.3 * (1.0 - a * a).sqrt() * normal(&mut g);
            trend(t) + ar
        })
        .collect();
    (t, y, trend)
}

#[test]
fn horizon_criterion_selects_models_that_extrapolate() {
    // Correlated noise fools the alternating split (neighbouring samples
    // agree), so regularity alone fits the wiggles with slow harmonics and
    // high powers that extrapolate wildly; the balance of forecasts over the
    // horizon sees that the early and late halves disagree beyond the record.
    let two_pi = 2.0 * std::f64::consts::PI;
    let base = GmdhConfig {
        search: Some(FrequencyGrid {
            min: two_pi / 5000.0,
            max: two_pi / 50.0,
            count: 20,
        }),
        max_units: 3,
        ..GmdhConfig::default()
    };
    let horizon = GmdhConfig {
        horizon_s: Some(1000.0),
        ..base.clone()
    };
    let (mut plain_sq, mut horizon_sq) = (0.0, 0.0);
    for seed in 1..=12 {
        let (t, y, trend) = trend_under_correlated_noise(seed);
        let plain = select(&t, &y, &base).unwrap().model;
        let aware = select(&t, &y, &horizon).unwrap().model;
        for k in 1..=100 {
            let tf = 995.0 + 10.0 * k as f64;
            plain_sq += (plain.predict(tf) - trend(tf)).powi(2);
            horizon_sq += (aware.predict(tf) - trend(tf)).powi(2);
        }
    }
    let (plain_rms, horizon_rms) = ((plain_sq / 1200.0).sqrt(), (horizon_sq / 1200.0).sqrt());
    assert!(
        horizon_rms < 0.5 * plain_rms,
        "forecast RMS over 1000 s: with horizon {horizon_rms}, without {plain_rms}"
    );
}

#[test]
fn horizon_criterion_keeps_a_true_structure() {
    // When the record holds the whole structure, both halves agree and the
    // balance term is ≈ 0: the known trend + sinusoid is still found and
    // extrapolates exactly.
    let w = 2.0 * std::f64::consts::PI / 50.0;
    let t: Vec<f64> = (0..200).map(|k| k as f64).collect();
    let f = |t: f64| 0.5 + 0.01 * t + 2.0 * (w * t).sin();
    let y: Vec<f64> = t.iter().map(|&t| f(t)).collect();
    let config = GmdhConfig {
        frequencies: vec![w],
        horizon_s: Some(500.0),
        ..GmdhConfig::default()
    };
    let sel = select(&t, &y, &config).unwrap();
    assert!((sel.model.predict(600.0) - f(600.0)).abs() < 1e-6);
    assert_eq!(sel.model.units.len(), 3, "{:?}", sel.model.units);
}

#[test]
fn horizon_must_be_positive() {
    let t: Vec<f64> = (0..50).map(f64::from).collect();
    let config = GmdhConfig {
        horizon_s: Some(0.0),
        ..GmdhConfig::default()
    };
    assert!(select(&t, &t, &config).is_err());
}
