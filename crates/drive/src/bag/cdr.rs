//! A small reader of ROS 2's CDR encoding (OMG XCDR1 "plain CDR", what `rmw` writes): a 4-byte
//! encapsulation header (`00 01` little-endian, `00 00` big-endian, then two option bytes), then
//! the fields in declaration order, each primitive aligned to its size (8 for `float64`) counted
//! from the end of the header; strings as a `uint32` length that includes a NUL terminator;
//! sequences as a `uint32` count then the elements; fixed arrays with no count.
//!
//! Every read is bounds-checked and every count is checked against the bytes that remain before
//! anything is allocated for it, so a hostile length can only produce an error.

/// Why a CDR buffer could not be decoded (the caller adds file, topic and message).
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) struct CdrError(pub String);

impl std::fmt::Display for CdrError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

pub(crate) type CdrResult<T> = Result<T, CdrError>;

/// A cursor over one CDR message.
pub(crate) struct Cdr<'a> {
    /// The message after the encapsulation header.
    body: &'a [u8],
    pos: usize,
    little: bool,
}

impl<'a> Cdr<'a> {
    /// Reads the encapsulation header.
    pub(crate) fn new(bytes: &'a [u8]) -> CdrResult<Self> {
        let (header, body) = bytes.split_at_checked(4).ok_or_else(|| {
            CdrError(format!(
                "{} bytes, shorter than the 4-byte CDR header",
                bytes.len()
            ))
        })?;
        let little = match (header[0], header[1]) {
            (0, 1) => true,
            (0, 0) => false,
            (a, b) => {
                return Err(CdrError(format!(
                    "encapsulation {a:02x} {b:02x} is not plain CDR (00 00 or 00 01)"
                )));
            }
        };
        Ok(Self {
            body,
            pos: 0,
            little,
        })
    }

    /// Bytes left after the cursor.
    pub(crate) fn remaining(&self) -> usize {
        self.body.len().saturating_sub(self.pos)
    }

    fn align(&mut self, n: usize) -> CdrResult<()> {
        let pad = (n - self.pos % n) % n;
        if pad > self.remaining() {
            return Err(self.short(pad, "alignment padding"));
        }
        self.pos += pad;
        Ok(())
    }

    fn short(&self, need: usize, what: &str) -> CdrError {
        CdrError(format!(
            "truncated: {what} needs {need} bytes at offset {}, {} left",
            self.pos + 4,
            self.remaining()
        ))
    }

    /// The next `n` bytes, unaligned.
    pub(crate) fn bytes(&mut self, n: usize, what: &str) -> CdrResult<&'a [u8]> {
        if n > self.remaining() {
            return Err(self.short(n, what));
        }
        let out = &self.body[self.pos..self.pos + n];
        self.pos += n;
        Ok(out)
    }

    fn array<const N: usize>(&mut self, what: &str) -> CdrResult<[u8; N]> {
        self.align(N)?;
        let b = self.bytes(N, what)?;
        let mut out = [0u8; N];
        out.copy_from_slice(b);
        if self.little == cfg!(target_endian = "big") {
            out.reverse();
        }
        Ok(out)
    }

    pub(crate) fn u8(&mut self, what: &str) -> CdrResult<u8> {
        Ok(self.bytes(1, what)?[0])
    }

    pub(crate) fn bool(&mut self, what: &str) -> CdrResult<bool> {
        match self.u8(what)? {
            0 => Ok(false),
            1 => Ok(true),
            v => Err(CdrError(format!("{what}: bool byte {v}, not 0 or 1"))),
        }
    }

    pub(crate) fn u16(&mut self, what: &str) -> CdrResult<u16> {
        Ok(u16::from_ne_bytes(self.array(what)?))
    }

    pub(crate) fn i32(&mut self, what: &str) -> CdrResult<i32> {
        Ok(i32::from_ne_bytes(self.array(what)?))
    }

    pub(crate) fn u32(&mut self, what: &str) -> CdrResult<u32> {
        Ok(u32::from_ne_bytes(self.array(what)?))
    }

    pub(crate) fn f64(&mut self, what: &str) -> CdrResult<f64> {
        Ok(f64::from_ne_bytes(self.array(what)?))
    }

    /// A sequence count, checked so that `count` elements of at least `min_size` bytes each fit
    /// in what remains.
    pub(crate) fn count(&mut self, min_size: usize, what: &str) -> CdrResult<usize> {
        let n = self.u32(what)? as usize;
        let need = n.checked_mul(min_size.max(1));
        match need {
            Some(need) if need <= self.remaining() => Ok(n),
            _ => Err(CdrError(format!(
                "{what}: count {n} (at least {} bytes each) does not fit in the {} bytes left",
                min_size.max(1),
                self.remaining()
            ))),
        }
    }

    /// A `string`: length with terminator, UTF-8 content, NUL.
    pub(crate) fn string(&mut self, what: &str) -> CdrResult<String> {
        let n = self.count(1, what)?;
        let raw = self.bytes(n, what)?;
        // ROS 2 always writes the terminator; some writers of empty strings write length 0.
        let text = match raw.split_last() {
            Some((0, text)) => text,
            Some(_) => return Err(CdrError(format!("{what}: string without NUL terminator"))),
            None => raw,
        };
        String::from_utf8(text.to_vec())
            .map_err(|_| CdrError(format!("{what}: string is not UTF-8")))
    }

    /// A `uint8[]`: count then raw bytes.
    pub(crate) fn byte_seq(&mut self, what: &str) -> CdrResult<&'a [u8]> {
        let n = self.count(1, what)?;
        self.bytes(n, what)
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    #[test]
    fn reads_aligned_primitives_both_endians() {
        // LE: u8 1, pad to 4, u32 7, pad to 8 (from body start), f64 1.5.
        let mut le = vec![0, 1, 0, 0, 1, 0, 0, 0, 7, 0, 0, 0];
        le.extend_from_slice(&1.5f64.to_le_bytes());
        let mut c = Cdr::new(&le).unwrap();
        assert_eq!(c.u8("a").unwrap(), 1);
        assert_eq!(c.u32("b").unwrap(), 7);
        assert_eq!(c.f64("c").unwrap(), 1.5);
        assert_eq!(c.remaining(), 0);
        let mut be = vec![0, 0, 0, 0, 0, 0, 0, 7, 0, 0, 0, 0];
        be.extend_from_slice(&1.5f64.to_be_bytes());
        let mut c = Cdr::new(&be).unwrap();
        assert_eq!(c.u32("b").unwrap(), 7);
        assert_eq!(c.f64("c").unwrap(), 1.5);
    }

    #[test]
    fn strings_and_hostile_counts() {
        let msg = [0, 1, 0, 0, 3, 0, 0, 0, b'h', b'i', 0];
        assert_eq!(Cdr::new(&msg).unwrap().string("s").unwrap(), "hi");
        // No terminator.
        let msg = [0, 1, 0, 0, 2, 0, 0, 0, b'h', b'i'];
        assert!(Cdr::new(&msg).unwrap().string("s").is_err());
        // A count of 4 billion is refused before any allocation.
        let msg = [0, 1, 0, 0, 0xff, 0xff, 0xff, 0xff, 1, 2];
        let err = Cdr::new(&msg).unwrap().byte_seq("data").unwrap_err();
        assert!(err.0.contains("does not fit"), "{err}");
        let err = Cdr::new(&msg).unwrap().count(48, "transforms").unwrap_err();
        assert!(err.0.contains("4294967295"), "{err}");
        // Truncated primitive, bad header, bad bool.
        assert!(Cdr::new(&[0, 1, 0, 0, 1, 2]).unwrap().u32("x").is_err());
        assert!(Cdr::new(&[0, 1]).is_err());
        assert!(Cdr::new(&[0, 7, 0, 0]).is_err());
        assert!(Cdr::new(&[0, 1, 0, 0, 2]).unwrap().bool("b").is_err());
    }
}
