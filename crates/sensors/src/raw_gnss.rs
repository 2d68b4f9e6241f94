//! Raw GNSS measurements: what a receiver measures per satellite and
//! signal before it solves for a position (u-blox RXM-RAWX, a RINEX
//! observation epoch). The tightly coupled filter and a single-point
//! solution take these instead of [`GnssFix`](crate::GnssFix)es.

/// A satellite system.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Constellation {
    /// GPS (USA).
    Gps,
    /// SBAS (WAAS, EGNOS, MSAS, GAGAN …).
    Sbas,
    /// Galileo (EU).
    Galileo,
    /// BeiDou (China).
    Beidou,
    /// QZSS (Japan).
    Qzss,
    /// GLONASS (Russia).
    Glonass,
    /// NavIC / IRNSS (India).
    Navic,
}

/// A satellite of a system, by its number within the system (PRN for
/// GPS, Galileo, BeiDou and QZSS; slot for GLONASS).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct SatelliteId {
    /// The system.
    pub constellation: Constellation,
    /// The satellite's number within it.
    pub number: u16,
}

/// A measured value and the σ the receiver gives it (when it does).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Measured {
    /// The value.
    pub value: f64,
    /// Its σ, in the value's unit.
    pub sigma: Option<f64>,
}

/// One signal of one satellite at an epoch. Each measurement is absent
/// when the receiver marks it invalid.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RawObservation {
    /// The satellite.
    pub satellite: SatelliteId,
    /// The signal within the system, as the receiver numbers it (u-blox
    /// `sigId`: e.g. GPS 0 = L1 C/A, 3 = L2 CL, 4 = L2 CM).
    pub signal: u8,
    /// GLONASS frequency channel (−7 … 6; None for the other systems).
    pub glonass_channel: Option<i8>,
    /// Pseudorange \[m\].
    pub pseudorange_m: Option<Measured>,
    /// Carrier phase \[cycles\], its half-cycle ambiguity resolved or not.
    pub carrier_phase_cycles: Option<(Measured, bool)>,
    /// Doppler \[Hz\] (positive for an approaching satellite).
    pub doppler_hz: Option<f64>,
    /// Carrier-to-noise density ratio \[dB-Hz\].
    pub cn0_dbhz: f64,
    /// Time the carrier has been tracked without a cycle slip \[s\].
    pub lock_time_s: f64,
}

/// Every raw observation of one receiver epoch.
#[derive(Debug, Clone, PartialEq)]
pub struct RawGnssEpoch {
    /// Receiver time of the measurements, GPST seconds since 1970-01-01
    /// (the receiver clock's offset is still in it).
    pub time_s: f64,
    /// The leap seconds GPST − UTC the receiver reports, when it knows.
    pub leap_seconds: Option<i8>,
    /// The observations, in the receiver's order.
    pub observations: Vec<RawObservation>,
}

impl RawGnssEpoch {
    /// The satellites observed (each once, in order), of the signals with
    /// a pseudorange.
    pub fn satellites_with_pseudorange(&self) -> Vec<SatelliteId> {
        let mut ids: Vec<SatelliteId> = self
            .observations
            .iter()
            .filter(|o| o.pseudorange_m.is_some())
            .map(|o| o.satellite)
            .collect();
        ids.sort_unstable();
        ids.dedup();
        ids
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Timed, merge};

    fn observation(
        constellation: Constellation,
        number: u16,
        range: Option<f64>,
    ) -> RawObservation {
        RawObservation {
            satellite: SatelliteId {
                constellation,
                number,
            },
            signal: 0,
            glonass_channel: None,
            pseudorange_m: range.map(|value| Measured {
                value,
                sigma: Some(3.0),
            }),
            carrier_phase_cycles: None,
            doppler_hz: Some(-512.0),
            cn0_dbhz: 40.0,
            lock_time_s: 1.0,
        }
    }

    #[test]
    fn an_epoch_lists_its_satellites_once_and_merges_by_time() {
        let epoch = RawGnssEpoch {
            time_s: 10.0,
            leap_seconds: Some(18),
            observations: vec![
                observation(Constellation::Galileo, 11, Some(2.3e7)),
                observation(Constellation::Gps, 5, Some(2.1e7)),
                observation(Constellation::Gps, 5, Some(2.1e7 + 3.0)),
                observation(Constellation::Gps, 9, None),
            ],
        };
        let ids = epoch.satellites_with_pseudorange();
        assert_eq!(ids.len(), 2);
        assert_eq!(ids[0].constellation, Constellation::Gps);
        assert_eq!(ids[1].number, 11);
        assert_eq!(epoch.time_s(), 10.0);
        // Raw epochs merge with the other streams.
        let raw = vec![
            epoch.clone(),
            RawGnssEpoch {
                time_s: 11.0,
                ..epoch
            },
        ];
        let baro = vec![crate::BaroSample {
            time_s: 10.5,
            height_m: 0.0,
            sigma_m: None,
        }];
        let order: Vec<(usize, usize)> = merge(&[&raw, &baro]).collect();
        assert_eq!(order, [(0, 0), (1, 0), (0, 1)]);
    }
}
