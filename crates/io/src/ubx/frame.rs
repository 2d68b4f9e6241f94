//! UBX framing: `0xB5 0x62`, class, id, payload length (u16, little-endian),
//! payload, and the 8-bit Fletcher checksum (CK_A, CK_B) over class … payload
//! (u-blox protocol specification, "UBX frame structure" and "UBX checksum").
//!
//! The scan looks for the sync pair at every byte. A frame whose checksum
//! fails, or that would run past the end of the bytes, is counted and the
//! scan resumes at the byte after its first sync byte — so a false sync
//! inside an NMEA sentence or inside a damaged frame never swallows the
//! frames that follow. Bytes outside frames (NMEA, RTCM, noise) are counted.
//!
//! Cost: checking a candidate frame would take time proportional to its
//! length (up to 65 535 bytes), and every byte can start a candidate, which
//! makes a naive scan quadratic on hostile input. The checksum of any byte
//! range is therefore taken from two prefix sums in constant time
//! ([`Fletcher`]), so the whole scan is linear in the input, with 2 bytes of
//! memory per input byte.

/// First sync byte (`µ`).
pub const SYNC_1: u8 = 0xB5;
/// Second sync byte (`b`).
pub const SYNC_2: u8 = 0x62;
/// Sync (2), class, id, length (2): the bytes before the payload.
pub const HEADER_LEN: usize = 6;
/// Header and the two checksum bytes: a frame is this plus its payload.
pub const OVERHEAD: usize = HEADER_LEN + 2;

/// The 8-bit Fletcher checksum of any range of a byte string in O(1), from
/// prefix sums mod 256.
///
/// With `S1[k] = Σ_{j<k} x_j` and `S2[k] = Σ_{i=1..k} S1[i]`, the range
/// `[s, e)` has `CK_A = S1[e] − S1[s]` and, since `CK_B` sums the running
/// `CK_A` after each byte, `CK_B = Σ_{m=s+1..e} (S1[m] − S1[s]) =
/// S2[e] − S2[s] − (e − s)·S1[s]`, all mod 256 (wrapping `u8` arithmetic is
/// exact mod 256).
#[derive(Debug, Clone)]
pub struct Fletcher {
    s1: Vec<u8>,
    s2: Vec<u8>,
}

impl Fletcher {
    /// The prefix sums of `bytes`.
    pub fn new(bytes: &[u8]) -> Self {
        let mut s1 = Vec::with_capacity(bytes.len() + 1);
        let mut s2 = Vec::with_capacity(bytes.len() + 1);
        let (mut a, mut b) = (0u8, 0u8);
        s1.push(a);
        s2.push(b);
        for &x in bytes {
            a = a.wrapping_add(x);
            b = b.wrapping_add(a);
            s1.push(a);
            s2.push(b);
        }
        Self { s1, s2 }
    }

    /// `(CK_A, CK_B)` of the bytes `[start, end)`, or `None` when the range
    /// is not inside the bytes.
    pub fn range(&self, start: usize, end: usize) -> Option<(u8, u8)> {
        if start > end {
            return None;
        }
        let (a0, a1) = (*self.s1.get(start)?, *self.s1.get(end)?);
        let (b0, b1) = (*self.s2.get(start)?, *self.s2.get(end)?);
        // (e − s) mod 256: the truncation is the reduction.
        let n = (end - start) as u8;
        Some((
            a1.wrapping_sub(a0),
            b1.wrapping_sub(b0).wrapping_sub(n.wrapping_mul(a0)),
        ))
    }
}

/// One checksummed UBX frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Frame<'a> {
    /// Byte offset of its first sync byte.
    pub offset: usize,
    /// Message class.
    pub class: u8,
    /// Message id.
    pub id: u8,
    /// Payload.
    pub payload: &'a [u8],
}

/// What a scan met besides good frames.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ScanCounts {
    /// Bytes outside any good frame (other protocols, noise, damaged frames).
    pub outside_bytes: usize,
    /// Candidate frames whose checksum failed.
    pub bad_checksum: usize,
    /// Offset of the first of them.
    pub first_bad_checksum: Option<usize>,
    /// Candidate frames running past the end of the bytes.
    pub truncated: usize,
    /// Offset of the first of them.
    pub first_truncated: Option<usize>,
}

/// Every checksummed frame of `bytes`, in order, and the counts of what
/// else the scan met (see the module docs).
///
/// ```
/// use aidnav_io::ubx::frame::{frames, encode};
/// let mut log = b"$GPGGA,junk*00\r\n".to_vec();
/// log.extend(encode(0x01, 0x07, &[1, 2, 3]));
/// let (found, counts) = frames(&log);
/// assert_eq!(found.len(), 1);
/// assert_eq!((found[0].offset, found[0].payload), (16, &[1u8, 2, 3][..]));
/// assert_eq!(counts.outside_bytes, 16);
/// ```
pub fn frames(bytes: &[u8]) -> (Vec<Frame<'_>>, ScanCounts) {
    let sums = Fletcher::new(bytes);
    let mut found = Vec::new();
    let mut counts = ScanCounts::default();
    let mut at = 0usize;
    let mut outside_from = 0usize;
    while let Some(rel) = find_sync(bytes.get(at..).unwrap_or(&[])) {
        let start = at + rel;
        match frame_at(bytes, &sums, start) {
            Candidate::Good(frame, len) => {
                counts.outside_bytes += start - outside_from;
                found.push(frame);
                at = start + len;
                outside_from = at;
            }
            Candidate::BadChecksum => {
                counts.bad_checksum += 1;
                counts.first_bad_checksum.get_or_insert(start);
                at = start + 1;
            }
            Candidate::Truncated => {
                counts.truncated += 1;
                counts.first_truncated.get_or_insert(start);
                at = start + 1;
            }
        }
    }
    counts.outside_bytes += bytes.len().saturating_sub(outside_from);
    (found, counts)
}

/// Offset of the next `0xB5 0x62` pair in `bytes`.
fn find_sync(bytes: &[u8]) -> Option<usize> {
    bytes.windows(2).position(|w| w == [SYNC_1, SYNC_2])
}

enum Candidate<'a> {
    /// A frame and its total length.
    Good(Frame<'a>, usize),
    BadChecksum,
    Truncated,
}

/// The frame whose sync starts at `start`.
fn frame_at<'a>(bytes: &'a [u8], sums: &Fletcher, start: usize) -> Candidate<'a> {
    let Some(&[_, _, class, id, l0, l1]) = bytes.get(start..start + HEADER_LEN) else {
        return Candidate::Truncated;
    };
    let len = usize::from(u16::from_le_bytes([l0, l1]));
    let payload_end = start + HEADER_LEN + len;
    let (Some(payload), Some(&[ck_a, ck_b])) = (
        bytes.get(start + HEADER_LEN..payload_end),
        bytes.get(payload_end..payload_end + 2),
    ) else {
        return Candidate::Truncated;
    };
    // The checksum covers class, id, length and payload.
    match sums.range(start + 2, payload_end) {
        Some(sum) if sum == (ck_a, ck_b) => Candidate::Good(
            Frame {
                offset: start,
                class,
                id,
                payload,
            },
            OVERHEAD + len,
        ),
        _ => Candidate::BadChecksum,
    }
}

/// A UBX frame with its checksum (for tests, seeds and examples); a payload
/// longer than 65 535 bytes is cut to that length.
pub fn encode(class: u8, id: u8, payload: &[u8]) -> Vec<u8> {
    let payload = payload.get(..usize::from(u16::MAX)).unwrap_or(payload);
    let len = payload.len() as u16;
    let mut out = vec![SYNC_1, SYNC_2, class, id];
    out.extend(len.to_le_bytes());
    out.extend(payload);
    let (mut a, mut b) = (0u8, 0u8);
    for &x in out.get(2..).unwrap_or(&[]) {
        a = a.wrapping_add(x);
        b = b.wrapping_add(a);
    }
    out.extend([a, b]);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The checksum the protocol specification spells out, byte by byte.
    fn direct(bytes: &[u8]) -> (u8, u8) {
        bytes.iter().fold((0u8, 0u8), |(a, b), &x| {
            let a = a.wrapping_add(x);
            (a, b.wrapping_add(a))
        })
    }

    #[test]
    fn prefix_sums_give_the_checksum_of_every_range() {
        // A pseudo-random string long enough for the (e − s) mod 256 term
        // to wrap several times.
        let bytes: Vec<u8> = (0u32..1500)
            .map(|k| (k.wrapping_mul(2_654_435_761) >> 13) as u8)
            .collect();
        let f = Fletcher::new(&bytes);
        for (s, e) in [(0, 0), (0, 1), (3, 300), (17, 1500), (256, 512), (1, 1499)] {
            assert_eq!(f.range(s, e), Some(direct(&bytes[s..e])), "[{s}, {e})");
        }
        assert_eq!(f.range(2, 1), None);
        assert_eq!(f.range(0, 1501), None);
    }

    #[test]
    fn nav_pvt_of_the_protocol_example_checks() {
        // An empty NAV-PVT poll request: B5 62 01 07 00 00, checksum 08 19
        // (u-blox protocol specification's polling example).
        assert_eq!(
            encode(0x01, 0x07, &[]),
            [0xB5, 0x62, 0x01, 0x07, 0, 0, 0x08, 0x19]
        );
    }

    #[test]
    fn bad_checksums_and_truncation_resynchronise() {
        let a = encode(0x01, 0x07, &[9; 10]);
        let b = encode(0x02, 0x15, &[7; 4]);
        let mut damaged = a.clone();
        damaged[8] ^= 0xFF;
        // A damaged frame, a good one, a false sync announcing 0xFFFF bytes,
        // a good one, then a frame cut short.
        let mut log = damaged.clone();
        log.extend(&b);
        log.extend([0xB5, 0x62, 0x01, 0x07, 0xFF, 0xFF, 1, 2]);
        log.extend(&a);
        log.extend(&b[..7]);
        let (found, counts) = frames(&log);
        assert_eq!(
            found
                .iter()
                .map(|f| (f.offset, f.class))
                .collect::<Vec<_>>(),
            [(damaged.len(), 0x02), (damaged.len() + b.len() + 8, 0x01)]
        );
        assert_eq!(counts.bad_checksum, 1);
        assert_eq!(counts.first_bad_checksum, Some(0));
        // The false sync and the cut frame run past the end.
        assert_eq!(counts.truncated, 2);
        assert_eq!(counts.first_truncated, Some(damaged.len() + b.len()));
        assert_eq!(counts.outside_bytes, damaged.len() + 8 + 7);
    }

    #[test]
    fn a_frame_right_after_a_lone_sync_byte_is_found() {
        let mut log = vec![SYNC_1];
        log.extend(encode(0x01, 0x07, &[1]));
        let (found, counts) = frames(&log);
        assert_eq!(found.len(), 1);
        assert_eq!((found[0].offset, counts.outside_bytes), (1, 1));
        assert_eq!(frames(&[]).0.len(), 0);
        assert_eq!(frames(&[SYNC_1, SYNC_2]).1.truncated, 1);
    }
}
