//! Input mutation: byte-level edits as libFuzzer does, plus edits that know text formats are made
//! of numbers and words, which is where header counts and sizes hide.

/// The mutation stream: SplitMix64 (Steele, Lea & Flood 2014; the bench's generator too, the
/// same sequence for a seed), so that a run is replayed from its seed alone. Its own copy, so
/// that the fuzzer does not depend on the bench for fourteen lines.
#[derive(Clone, Debug)]
pub struct Rng(u64);

impl Rng {
    /// A generator whose whole sequence follows from `seed`.
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// A uniform index below `n` (`n > 0`); the modulo bias is irrelevant here.
    pub fn below(&mut self, n: usize) -> usize {
        (self.next_u64() % n.max(1) as u64) as usize
    }

    /// True with probability `1 / n`.
    pub fn one_in(&mut self, n: usize) -> bool {
        self.below(n) == 0
    }
}

/// Numbers that break size arithmetic, parsers and float handling: boundaries of the integer
/// types, huge and negative counts, non-finite and denormal floats.
pub const INTERESTING_NUMBERS: &[&str] = &[
    "0",
    "-0",
    "1",
    "-1",
    "2",
    "255",
    "256",
    "65535",
    "65536",
    "2147483647",
    "2147483648",
    "-2147483648",
    "4294967295",
    "4294967296",
    "4000000000",
    "1000000000000",
    "9223372036854775807",
    "9223372036854775808",
    "18446744073709551612",
    "18446744073709551615",
    "18446744073709551616",
    "1e9",
    "1e308",
    "-1e308",
    "1e-320",
    "NaN",
    "nan",
    "inf",
    "-inf",
    "Infinity",
    "1.7976931348623157e309",
    "0.5",
    "-180.0000001",
    "95",
    "1000",
    "",
];

/// Bytes inserted or overwritten by the byte-level edits.
const INTERESTING_BYTES: &[u8] = &[
    0, 0x7f, 0x80, 0xff, b'\n', b' ', b'#', b'-', b'.', b'"', b'<', b'{',
];

/// Produces one mutant of `input`, sometimes spliced with `other` (another corpus entry), never
/// longer than `max_len` bytes.
pub fn mutate(rng: &mut Rng, input: &[u8], other: &[u8], max_len: usize) -> Vec<u8> {
    let mut out = input.to_vec();
    // Stacked edits, as libFuzzer does: a single edit rarely gets past a second check.
    let edits = 1 + rng.below(4);
    for _ in 0..edits {
        match rng.below(11) {
            0 => flip_bit(rng, &mut out),
            1 => set_byte(rng, &mut out),
            2 => insert_bytes(rng, &mut out),
            3 => delete_range(rng, &mut out),
            4 => duplicate_range(rng, &mut out),
            5 => truncate(rng, &mut out),
            6 => splice(rng, &mut out, other),
            7 | 8 => replace_number(rng, &mut out),
            9 => set_word_bytes(rng, &mut out),
            _ => swap_lines(rng, &mut out),
        }
    }
    out.truncate(max_len);
    out
}

fn flip_bit(rng: &mut Rng, data: &mut [u8]) {
    if !data.is_empty() {
        let i = rng.below(data.len());
        data[i] ^= 1 << rng.below(8);
    }
}

fn set_byte(rng: &mut Rng, data: &mut [u8]) {
    if !data.is_empty() {
        let i = rng.below(data.len());
        data[i] = if rng.one_in(2) {
            INTERESTING_BYTES[rng.below(INTERESTING_BYTES.len())]
        } else {
            rng.next_u64() as u8
        };
    }
}

fn insert_bytes(rng: &mut Rng, data: &mut Vec<u8>) {
    let at = rng.below(data.len() + 1);
    let n = 1 + rng.below(8);
    let bytes: Vec<u8> = (0..n)
        .map(|_| INTERESTING_BYTES[rng.below(INTERESTING_BYTES.len())])
        .collect();
    data.splice(at..at, bytes);
}

fn delete_range(rng: &mut Rng, data: &mut Vec<u8>) {
    if !data.is_empty() {
        let start = rng.below(data.len());
        let len = 1 + rng.below((data.len() - start).min(64));
        data.drain(start..start + len);
    }
}

fn duplicate_range(rng: &mut Rng, data: &mut Vec<u8>) {
    if !data.is_empty() {
        let start = rng.below(data.len());
        let len = 1 + rng.below((data.len() - start).min(256));
        let copy = data[start..start + len].to_vec();
        let at = rng.below(data.len() + 1);
        data.splice(at..at, copy);
    }
}

fn truncate(rng: &mut Rng, data: &mut Vec<u8>) {
    let keep = rng.below(data.len() + 1);
    data.truncate(keep);
}

fn splice(rng: &mut Rng, data: &mut Vec<u8>, other: &[u8]) {
    if other.is_empty() {
        return;
    }
    let from = rng.below(other.len());
    let len = 1 + rng.below((other.len() - from).min(512));
    let at = rng.below(data.len() + 1);
    let end = (at + rng.below(len + 1)).min(data.len());
    data.splice(at..end, other[from..from + len].iter().copied());
}

/// Spans of ASCII numbers (digits with sign, point and exponent) in `data`.
fn number_spans(data: &[u8]) -> Vec<(usize, usize)> {
    let mut spans = Vec::new();
    let mut i = 0;
    while i < data.len() {
        if data[i].is_ascii_digit() {
            let mut start = i;
            if start > 0 && data[start - 1] == b'-' {
                start -= 1;
            }
            while i < data.len() && (data[i].is_ascii_digit() || b".eE+-".contains(&data[i])) {
                i += 1;
            }
            spans.push((start, i));
        } else {
            i += 1;
        }
    }
    spans
}

fn replace_number(rng: &mut Rng, data: &mut Vec<u8>) {
    let spans = number_spans(data);
    if spans.is_empty() {
        return;
    }
    let (start, end) = spans[rng.below(spans.len())];
    let replacement = INTERESTING_NUMBERS[rng.below(INTERESTING_NUMBERS.len())];
    data.splice(start..end, replacement.bytes());
}

/// Overwrites a word (a run of letters) with another word of the input: turns `ascii` into
/// `binary`, `F` into `U`, `x` into `rgb`, a tag key into a value.
fn set_word_bytes(rng: &mut Rng, data: &mut Vec<u8>) {
    let words: Vec<(usize, usize)> = {
        let mut spans = Vec::new();
        let mut i = 0;
        while i < data.len() {
            if data[i].is_ascii_alphabetic() {
                let start = i;
                while i < data.len() && (data[i].is_ascii_alphanumeric() || data[i] == b'_') {
                    i += 1;
                }
                spans.push((start, i));
            } else {
                i += 1;
            }
        }
        spans
    };
    if words.len() < 2 {
        return;
    }
    let (a_start, a_end) = words[rng.below(words.len())];
    let (b_start, b_end) = words[rng.below(words.len())];
    let word = data[b_start..b_end].to_vec();
    data.splice(a_start..a_end, word);
}

fn swap_lines(rng: &mut Rng, data: &mut Vec<u8>) {
    let mut lines: Vec<&[u8]> = data.split(|&b| b == b'\n').collect();
    if lines.len() < 2 {
        return;
    }
    let (a, b) = (rng.below(lines.len()), rng.below(lines.len()));
    lines.swap(a, b);
    *data = lines.join(&b'\n');
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_stream_is_splitmix64() {
        // SplitMix64's published first outputs from seed 0 (the reference implementation's).
        let mut rng = Rng::new(0);
        assert_eq!(rng.next_u64(), 0xE220_A839_7B1D_CDAF);
        assert_eq!(rng.next_u64(), 0x6E78_9E6A_A1B9_65F4);
    }

    #[test]
    fn same_seed_same_mutants() {
        let input = b"WIDTH 10\nHEIGHT 1\nPOINTS 10\n";
        let run = |seed| {
            let mut rng = Rng::new(seed);
            (0..50)
                .map(|_| mutate(&mut rng, input, b"other 5", 1 << 12))
                .collect::<Vec<_>>()
        };
        assert_eq!(run(7), run(7));
        assert_ne!(run(7), run(8));
    }

    #[test]
    fn finds_numbers_with_signs_and_exponents() {
        let spans = number_spans(b"a -12.5e3 b 7");
        assert_eq!(spans, [(2, 9), (12, 13)]);
    }

    #[test]
    fn respects_the_length_bound() {
        let mut rng = Rng::new(1);
        let big = vec![b'1'; 1000];
        for _ in 0..200 {
            assert!(mutate(&mut rng, &big, &big, 1024).len() <= 1024);
        }
    }

    #[test]
    fn number_replacement_reaches_the_header_values() {
        let mut rng = Rng::new(3);
        let mut seen_huge = false;
        for _ in 0..500 {
            let mut data = b"POINTS 10".to_vec();
            replace_number(&mut rng, &mut data);
            seen_huge |= data == b"POINTS 18446744073709551615";
        }
        assert!(seen_huge);
    }
}
