//! Time order across streams: every record has a time ([`Timed`]), a
//! sequence of records is a [`Timeline`], and [`merge`] walks any number
//! of time-sorted timelines — of one record type or of several — in time
//! order, yielding `(stream, index)` pairs that point into the caller's own
//! slices.
//!
//! Order: by time, compared with [`f64::total_cmp`] (a total order, so a
//! NaN, which no reader lets through, cannot stall the walk: it sorts after
//! +∞); records at the same time come in stream order (the stream given
//! first, first), and within one stream in index order. That is exactly
//! the order of a stable sort of the streams' concatenation by time, which
//! the tests check.
//!
//! Cost: one allocation of one cursor per stream when the merge is made,
//! none per record; each step compares the streams' heads, O(streams) — a
//! linear scan beats a heap for the handful of sensors a vehicle carries.
//! A stream that is not sorted is still walked completely, each record
//! once, but the output is then only ordered among the streams' heads.

use crate::{BaroSample, GnssFix, ImuSample, RawGnssEpoch, WheelSpeedSample};

/// A record that carries its time.
pub trait Timed {
    /// GPST, seconds since 1970-01-01.
    fn time_s(&self) -> f64;
}

/// `Timed` for records whose time is their `time_s` field.
macro_rules! timed_by_field {
    ($($record:ty),*) => {
        $(impl Timed for $record {
            fn time_s(&self) -> f64 {
                self.time_s
            }
        })*
    };
}

timed_by_field!(
    ImuSample,
    GnssFix,
    WheelSpeedSample,
    BaroSample,
    RawGnssEpoch
);

/// A sequence of timed records, seen only through its length and the time
/// of each record: what [`merge`] needs, whatever the record type (so
/// streams of different types merge as `&dyn Timeline`).
pub trait Timeline {
    /// Number of records.
    fn records(&self) -> usize;
    /// Time of record `index` (< [`Timeline::records`]) \[s\].
    fn time_at(&self, index: usize) -> f64;
}

impl<T: Timed> Timeline for &[T] {
    fn records(&self) -> usize {
        self.len()
    }
    fn time_at(&self, index: usize) -> f64 {
        self[index].time_s()
    }
}

impl<T: Timed> Timeline for Vec<T> {
    fn records(&self) -> usize {
        self.len()
    }
    fn time_at(&self, index: usize) -> f64 {
        self[index].time_s()
    }
}

impl<T: Timed, const N: usize> Timeline for [T; N] {
    fn records(&self) -> usize {
        N
    }
    fn time_at(&self, index: usize) -> f64 {
        self[index].time_s()
    }
}

/// The records of several time-sorted streams in time order: an iterator
/// of `(stream, index)`, `stream` the position of the stream in the list
/// given to [`merge`], `index` the record's position in that stream. See
/// the module docs for the order and the cost.
#[derive(Clone)]
pub struct Merge<'a> {
    /// Each stream and the index of its next record.
    heads: Vec<(&'a dyn Timeline, usize)>,
    /// Records not yet yielded.
    remaining: usize,
}

/// Walk `streams` (each sorted by time) in time order, ties in stream
/// order; see [`Merge`].
///
/// ```
/// use aidnav_sensors::{BaroSample, WheelSpeedSample, merge};
/// let wheel = vec![
///     WheelSpeedSample { time_s: 0.0, speed_mps: 10.0, sigma_mps: None },
///     WheelSpeedSample { time_s: 0.1, speed_mps: 10.1, sigma_mps: None },
///     WheelSpeedSample { time_s: 0.2, speed_mps: 10.2, sigma_mps: None },
/// ];
/// let baro = [BaroSample { time_s: 0.1, height_m: 52.0, sigma_m: Some(0.5) }];
/// // At 0.1 s both report: the wheel, stream 0, comes first.
/// let order: Vec<(usize, usize)> = merge(&[&wheel, &baro]).collect();
/// assert_eq!(order, [(0, 0), (0, 1), (1, 0), (0, 2)]);
/// for (stream, index) in merge(&[&wheel, &baro]) {
///     match stream {
///         0 => assert!(wheel[index].speed_mps >= 10.0),
///         _ => assert_eq!(baro[index].height_m, 52.0),
///     }
/// }
/// ```
pub fn merge<'a>(streams: &[&'a dyn Timeline]) -> Merge<'a> {
    Merge {
        heads: streams.iter().map(|&s| (s, 0)).collect(),
        remaining: streams.iter().map(|s| s.records()).sum(),
    }
}

impl Iterator for Merge<'_> {
    type Item = (usize, usize);

    fn next(&mut self) -> Option<(usize, usize)> {
        let mut best: Option<(usize, f64)> = None;
        for (stream, &(timeline, index)) in self.heads.iter().enumerate() {
            if index >= timeline.records() {
                continue;
            }
            let t = timeline.time_at(index);
            // Strictly earlier only: an equal time keeps the earlier stream.
            if best.is_none_or(|(_, bt)| t.total_cmp(&bt).is_lt()) {
                best = Some((stream, t));
            }
        }
        let (stream, _) = best?;
        let head = &mut self.heads[stream].1;
        let index = *head;
        *head += 1;
        self.remaining -= 1;
        Some((stream, index))
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        (self.remaining, Some(self.remaining))
    }
}

impl ExactSizeIterator for Merge<'_> {}

impl std::iter::FusedIterator for Merge<'_> {}

impl std::fmt::Debug for Merge<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let heads: Vec<(usize, usize)> =
            self.heads.iter().map(|(t, i)| (*i, t.records())).collect();
        f.debug_struct("Merge")
            .field("heads (next, records)", &heads)
            .field("remaining", &self.remaining)
            .finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;
    use proptest::prelude::*;

    fn wheel(times: &[f64]) -> Vec<WheelSpeedSample> {
        times
            .iter()
            .map(|&time_s| WheelSpeedSample {
                time_s,
                speed_mps: 0.0,
                sigma_mps: None,
            })
            .collect()
    }

    /// The oracle: concatenate, then sort stably by time.
    fn sorted_concatenation(streams: &[Vec<f64>]) -> Vec<(usize, usize)> {
        let mut all: Vec<(f64, usize, usize)> = streams
            .iter()
            .enumerate()
            .flat_map(|(s, times)| times.iter().enumerate().map(move |(i, &t)| (t, s, i)))
            .collect();
        all.sort_by(|a, b| a.0.total_cmp(&b.0));
        all.into_iter().map(|(_, s, i)| (s, i)).collect()
    }

    #[test]
    fn records_of_different_types_merge() {
        let imu: Vec<ImuSample> = (0..5)
            .map(|k| ImuSample {
                time_s: 100.0 + 0.01 * k as f64,
                specific_force: Vector3::new(0.0, 0.0, -9.8),
                angular_rate: Vector3::zeros(),
            })
            .collect();
        let baro = [BaroSample {
            time_s: 100.02,
            height_m: 12.0,
            sigma_m: None,
        }];
        let empty: &[GnssFix] = &[];
        let order: Vec<_> = merge(&[&empty, &imu, &baro]).collect();
        assert_eq!(order, [(1, 0), (1, 1), (1, 2), (2, 0), (1, 3), (1, 4)]);
    }

    #[test]
    fn no_streams_or_empty_streams_yield_nothing() {
        assert_eq!(merge(&[]).next(), None);
        let none = wheel(&[]);
        let mut m = merge(&[&none, &none]);
        assert_eq!((m.len(), m.next(), m.next()), (0, None, None));
    }

    #[test]
    fn the_length_counts_down() {
        let (a, b) = (wheel(&[1.0, 2.0]), wheel(&[1.5]));
        let mut m = merge(&[&a, &b]);
        assert_eq!(m.len(), 3);
        m.next();
        assert_eq!(m.size_hint(), (2, Some(2)));
    }

    proptest! {
        /// Against sort-and-concatenate, with many ties (times on a coarse
        /// grid) and empty streams.
        #[test]
        fn merge_equals_a_stable_sort_of_the_concatenation(
            grids in proptest::collection::vec(proptest::collection::vec(0u8..20, 0..12), 0..6)
        ) {
            let times: Vec<Vec<f64>> = grids
                .iter()
                .map(|g| {
                    let mut t: Vec<f64> = g.iter().map(|&k| 0.5 * f64::from(k)).collect();
                    t.sort_by(f64::total_cmp);
                    t
                })
                .collect();
            let streams: Vec<Vec<WheelSpeedSample>> = times.iter().map(|t| wheel(t)).collect();
            let views: Vec<&dyn Timeline> = streams.iter().map(|s| s as &dyn Timeline).collect();
            let merged: Vec<(usize, usize)> = merge(&views).collect();
            prop_assert_eq!(merged, sorted_concatenation(&times));
        }
    }
}
