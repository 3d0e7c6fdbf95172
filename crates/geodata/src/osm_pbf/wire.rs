//! The protocol-buffer wire format, as far as the OSM PBF messages use it: varints, zigzag
//! integers, length-delimited fields and packed repeated fields; unknown fields are skipped.
//!
//! Nothing here allocates from a length read in the input: a length-delimited field is a slice
//! of the message it sits in, checked against the bytes that are left.

/// What is wrong with a message, in a few words (the caller adds which message it was).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct WireError(pub &'static str);

/// The value of one field, by wire type.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Value<'a> {
    /// Wire type 0.
    Varint(u64),
    /// Wire type 1 (read and ignored by the OSM messages).
    Fixed64(u64),
    /// Wire type 2: bytes, a string, a sub-message or a packed repeated field.
    Bytes(&'a [u8]),
    /// Wire type 5 (read and ignored by the OSM messages).
    Fixed32(u32),
}

/// The fields of one message in the order they are written.
pub(crate) struct Fields<'a> {
    bytes: &'a [u8],
    position: usize,
}

/// Iterates over the fields of `message` as (field number, value).
pub(crate) fn fields(message: &[u8]) -> Fields<'_> {
    Fields {
        bytes: message,
        position: 0,
    }
}

impl<'a> Fields<'a> {
    fn take(&mut self, length: usize) -> Result<&'a [u8], WireError> {
        let end = self
            .position
            .checked_add(length)
            .filter(|&end| end <= self.bytes.len())
            .ok_or(WireError("a field runs past the end of its message"))?;
        let slice = &self.bytes[self.position..end];
        self.position = end;
        Ok(slice)
    }

    fn field(&mut self) -> Result<(u32, Value<'a>), WireError> {
        let key = read_varint(self.bytes, &mut self.position)?;
        let number = u32::try_from(key >> 3)
            .ok()
            .filter(|&n| n > 0)
            .ok_or(WireError("invalid field number"))?;
        let value = match key & 7 {
            0 => Value::Varint(read_varint(self.bytes, &mut self.position)?),
            1 => {
                let raw = self.take(8)?;
                let mut word = [0; 8];
                word.copy_from_slice(raw);
                Value::Fixed64(u64::from_le_bytes(word))
            }
            2 => {
                let length = read_varint(self.bytes, &mut self.position)?;
                let length = usize::try_from(length)
                    .map_err(|_| WireError("a field runs past the end of its message"))?;
                Value::Bytes(self.take(length)?)
            }
            5 => {
                let raw = self.take(4)?;
                Value::Fixed32(u32::from_le_bytes([raw[0], raw[1], raw[2], raw[3]]))
            }
            _ => return Err(WireError("unsupported wire type")),
        };
        Ok((number, value))
    }
}

impl<'a> Iterator for Fields<'a> {
    type Item = Result<(u32, Value<'a>), WireError>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.position >= self.bytes.len() {
            return None;
        }
        let field = self.field();
        if field.is_err() {
            // Stop after the first error: the rest of the message cannot be framed.
            self.position = self.bytes.len();
        }
        Some(field)
    }
}

/// Reads a base-128 varint at `position`, at most 10 bytes.
fn read_varint(bytes: &[u8], position: &mut usize) -> Result<u64, WireError> {
    let mut value = 0u64;
    for shift in (0..70).step_by(7) {
        let &byte = bytes
            .get(*position)
            .ok_or(WireError("a varint runs past the end of its message"))?;
        *position += 1;
        if shift == 63 && byte > 1 {
            return Err(WireError("a varint is longer than 64 bits"));
        }
        value |= u64::from(byte & 0x7f) << shift;
        if byte & 0x80 == 0 {
            return Ok(value);
        }
    }
    Err(WireError("a varint is longer than 64 bits"))
}

/// The signed value of a zigzag-coded varint (`sint32`, `sint64`).
pub(crate) fn zigzag(raw: u64) -> i64 {
    ((raw >> 1) as i64) ^ -((raw & 1) as i64)
}

impl<'a> Value<'a> {
    /// The value of a varint field (`int32`, `int64`, `uint32`, `bool`, enum; the caller
    /// narrows it).
    pub(crate) fn varint(self) -> Result<u64, WireError> {
        match self {
            Value::Varint(raw) => Ok(raw),
            _ => Err(WireError("a number field has the wrong wire type")),
        }
    }

    /// The value of a zigzag-coded field (`sint64`).
    pub(crate) fn sint(self) -> Result<i64, WireError> {
        self.varint().map(zigzag)
    }

    /// The bytes of a length-delimited field (`bytes`, `string`, a sub-message).
    pub(crate) fn bytes(self) -> Result<&'a [u8], WireError> {
        match self {
            Value::Bytes(bytes) => Ok(bytes),
            _ => Err(WireError("a bytes field has the wrong wire type")),
        }
    }
}

/// The numbers of a repeated number field, read where they lie: every occurrence of field
/// `number` in `message`, packed (one length-delimited run) or not (one varint each), in order,
/// as the wire format allows a writer either. Nothing is collected: a hostile count costs no
/// memory.
pub(crate) fn repeated(message: &[u8], number: u32) -> Repeated<'_> {
    Repeated {
        fields: fields(message),
        number,
        run: &[],
        run_position: 0,
    }
}

/// Iterator of [`repeated`].
pub(crate) struct Repeated<'a> {
    fields: Fields<'a>,
    number: u32,
    run: &'a [u8],
    run_position: usize,
}

impl Iterator for Repeated<'_> {
    type Item = Result<u64, WireError>;

    fn next(&mut self) -> Option<Self::Item> {
        loop {
            if self.run_position < self.run.len() {
                let value = read_varint(self.run, &mut self.run_position);
                if value.is_err() {
                    self.stop();
                }
                return Some(value);
            }
            match self.fields.next()? {
                Ok((number, value)) if number == self.number => match value {
                    Value::Varint(raw) => return Some(Ok(raw)),
                    Value::Bytes(run) => {
                        self.run = run;
                        self.run_position = 0;
                    }
                    _ => {
                        self.stop();
                        return Some(Err(WireError(
                            "a repeated number field has the wrong wire type",
                        )));
                    }
                },
                Ok(_) => {}
                Err(error) => return Some(Err(error)),
            }
        }
    }
}

impl Repeated<'_> {
    fn stop(&mut self) {
        self.run = &[];
        self.run_position = 0;
        self.fields.position = self.fields.bytes.len();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn all(message: &[u8]) -> Result<Vec<(u32, Value<'_>)>, WireError> {
        fields(message).collect()
    }

    #[test]
    fn varints_of_one_to_ten_bytes_decode() {
        // 150 = 0x96 0x01 (the protobuf documentation's example); u64::MAX takes ten bytes.
        let mut position = 0;
        assert_eq!(read_varint(&[0x96, 0x01], &mut position), Ok(150));
        assert_eq!(position, 2);
        let max = [0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0x01];
        assert_eq!(read_varint(&max, &mut 0), Ok(u64::MAX));
    }

    #[test]
    fn overlong_and_truncated_varints_are_errors() {
        let too_long = [0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0x02];
        assert!(read_varint(&too_long, &mut 0).is_err());
        let eleven = [0x80; 11];
        assert!(read_varint(&eleven, &mut 0).is_err());
        assert!(read_varint(&[0x80, 0x80], &mut 0).is_err());
    }

    #[test]
    fn zigzag_alternates_signs() {
        // 0 → 0, 1 → -1, 2 → 1, 3 → -2, 4294967294 → 2147483647 (protobuf encoding guide).
        let decoded: Vec<i64> = [0, 1, 2, 3, 4_294_967_294].map(zigzag).to_vec();
        assert_eq!(decoded, vec![0, -1, 1, -2, 2_147_483_647]);
        assert_eq!(zigzag(u64::MAX), i64::MIN);
    }

    #[test]
    fn fields_of_every_wire_type_are_framed() -> Result<(), WireError> {
        // Field 1 varint 150; field 2 bytes "ab"; field 3 fixed64 1; field 4 fixed32 2.
        let message = [
            0x08, 0x96, 0x01, 0x12, 0x02, b'a', b'b', 0x19, 1, 0, 0, 0, 0, 0, 0, 0, 0x25, 2, 0, 0,
            0,
        ];
        let fields = all(&message)?;
        assert_eq!(
            fields,
            vec![
                (1, Value::Varint(150)),
                (2, Value::Bytes(b"ab")),
                (3, Value::Fixed64(1)),
                (4, Value::Fixed32(2)),
            ]
        );
        Ok(())
    }

    #[test]
    fn a_length_past_the_end_is_an_error_not_an_allocation() {
        // Field 2, length 2^62: must fail without reserving anything.
        let message = [0x12, 0x80, 0x80, 0x80, 0x80, 0x80, 0x80, 0x80, 0x80, 0x40];
        assert!(all(&message).is_err());
        assert!(all(&[0x12, 0x03, b'a']).is_err());
    }

    #[test]
    fn group_wire_types_and_field_zero_are_errors() {
        assert!(all(&[0x0b]).is_err(), "start group");
        assert!(all(&[0x00, 0x01]).is_err(), "field 0");
    }

    #[test]
    fn repeated_numbers_read_packed_or_one_by_one() -> Result<(), WireError> {
        // Field 2 packed [3, 270, 86942] (the protobuf guide's example), a field 1 between,
        // then field 2 once unpacked: 5.
        let message = [
            0x12, 0x06, 0x03, 0x8e, 0x02, 0x9e, 0xa7, 0x05, 0x08, 0x07, 0x10, 0x05,
        ];
        let numbers: Result<Vec<u64>, WireError> = repeated(&message, 2).collect();
        assert_eq!(numbers?, vec![3, 270, 86942, 5]);
        let ones: Result<Vec<u64>, WireError> = repeated(&message, 1).collect();
        assert_eq!(ones?, vec![7]);
        assert_eq!(repeated(&message, 3).count(), 0);
        Ok(())
    }

    #[test]
    fn a_broken_packed_run_ends_with_one_error() {
        // A run of one byte that is an unfinished varint.
        let numbers: Vec<_> = repeated(&[0x12, 0x01, 0x80, 0x10, 0x05], 2).collect();
        assert_eq!(numbers.len(), 1);
        assert!(numbers[0].is_err());
        let fixed: Vec<_> = repeated(&[0x15, 1, 0, 0, 0], 2).collect();
        assert_eq!(fixed.len(), 1);
        assert!(fixed[0].is_err());
    }

    #[test]
    fn wrong_wire_types_are_errors() {
        assert!(Value::Bytes(b"x").varint().is_err());
        assert!(Value::Varint(1).bytes().is_err());
    }
}
