//! LZ4-compressed MCAP chunks, decoded in Rust: the LZ4 frame format (lz4.org, "LZ4 Frame Format
//! Description" 1.6.x) around `lz4_flex`'s block decoder, registered with the MCAP reader in place
//! of its built-in decoder, which compiles the C liblz4.
//!
//! Frames may be concatenated and skippable frames are skipped. Blocks may be independent or
//! linked (a block may copy from the 64 KiB decoded before it, the `lz4` tool's default). The
//! frame's xxHash32 checksums are not verified: the chunk's CRC-32 of its uncompressed bytes,
//! which the MCAP reader checks, covers the same bytes. A frame with a preset dictionary is
//! refused.

use mcap::McapError;
use mcap::sans_io::decompressor::{DecompressResult, Decompressor};

/// The frame magic number, little-endian.
const FRAME_MAGIC: u32 = 0x184D_2204;
/// Skippable frames have magic numbers `0x184D2A50..=0x184D2A5F`.
const SKIPPABLE_MAGIC: u32 = 0x184D_2A50;
/// How far back a linked block may copy from.
const WINDOW_BYTES: usize = 64 * 1024;

/// Where the decoder is in the stream.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    /// Before a frame's magic number.
    FrameStart,
    /// Inside a frame, before a block's size.
    Block(Frame),
    /// Skipping the rest of a skippable frame.
    Skip(usize),
}

/// A frame's descriptor, as far as decoding needs it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Frame {
    linked: bool,
    block_checksum: bool,
    content_checksum: bool,
    max_block_bytes: usize,
}

/// The [`Decompressor`] for `"lz4"` chunks.
#[derive(Debug)]
pub(crate) struct Lz4Chunks {
    state: State,
    /// Compressed bytes taken from the reader, not yet decoded; `input[input_start..]` is left.
    input: Vec<u8>,
    input_start: usize,
    /// Decoded bytes not yet handed out; `output[output_start..]` is left.
    output: Vec<u8>,
    output_start: usize,
    /// The last decoded bytes of the frame, for linked blocks.
    window: Vec<u8>,
}

impl Lz4Chunks {
    /// A decoder ready for the first chunk.
    pub(crate) fn new() -> Self {
        Self {
            state: State::FrameStart,
            input: Vec::new(),
            input_start: 0,
            output: Vec::new(),
            output_start: 0,
            window: Vec::new(),
        }
    }

    fn pending(&self) -> &[u8] {
        &self.input[self.input_start..]
    }

    /// Takes `n` buffered bytes if there are that many.
    fn take(&mut self, n: usize) -> Option<&[u8]> {
        let start = self.input_start;
        let end = start
            .checked_add(n)
            .filter(|&end| end <= self.input.len())?;
        self.input_start = end;
        Some(&self.input[start..end])
    }

    /// Decodes what the buffered input allows, until one block's output is pending or more
    /// input is needed.
    fn advance(&mut self) -> Result<(), McapError> {
        while self.output_start == self.output.len() {
            let pending = self.pending();
            match self.state {
                State::Skip(left) => {
                    let n = left.min(pending.len());
                    if n == 0 && left > 0 {
                        return Ok(());
                    }
                    self.input_start += n;
                    self.state = if left == n {
                        State::FrameStart
                    } else {
                        State::Skip(left - n)
                    };
                }
                State::FrameStart => {
                    let Some(&magic) = pending.first_chunk::<4>() else {
                        return Ok(());
                    };
                    let magic = u32::from_le_bytes(magic);
                    if magic & 0xFFFF_FFF0 == SKIPPABLE_MAGIC {
                        let Some(&size) = pending.get(4..).and_then(|p| p.first_chunk::<4>())
                        else {
                            return Ok(());
                        };
                        self.input_start += 8;
                        self.state = State::Skip(u32::from_le_bytes(size) as usize);
                        continue;
                    }
                    if magic != FRAME_MAGIC {
                        return Err(error(format!("not an LZ4 frame (magic {magic:#010x})")));
                    }
                    let Some(frame) = read_descriptor(&pending[4..])? else {
                        return Ok(());
                    };
                    self.input_start += frame.1;
                    self.window.clear();
                    self.state = State::Block(frame.0);
                }
                State::Block(frame) => {
                    let Some(&size) = pending.first_chunk::<4>() else {
                        return Ok(());
                    };
                    let size = u32::from_le_bytes(size);
                    if size == 0 {
                        let trailer = 4 + if frame.content_checksum { 4 } else { 0 };
                        if self.take(trailer).is_none() {
                            return Ok(());
                        }
                        self.state = State::FrameStart;
                        continue;
                    }
                    let stored = size & 0x8000_0000 != 0;
                    let length = (size & 0x7FFF_FFFF) as usize;
                    if length > frame.max_block_bytes {
                        return Err(error(format!(
                            "an LZ4 block of {length} bytes, over the frame's {}",
                            frame.max_block_bytes
                        )));
                    }
                    let checksum = if frame.block_checksum { 4 } else { 0 };
                    if pending.len() < 4 + length + checksum {
                        return Ok(());
                    }
                    self.input_start += 4;
                    self.decode_block(frame, length, stored)?;
                    self.input_start += checksum;
                }
            }
        }
        Ok(())
    }

    /// Decodes the block of `length` bytes at the input's start into `output`.
    fn decode_block(&mut self, frame: Frame, length: usize, stored: bool) -> Result<(), McapError> {
        let block = &self.input[self.input_start..self.input_start + length];
        self.output.clear();
        self.output_start = 0;
        if stored {
            self.output.extend_from_slice(block);
        } else {
            self.output.resize(frame.max_block_bytes, 0);
            let dictionary: &[u8] = if frame.linked { &self.window } else { &[] };
            let n = lz4_flex::block::decompress_into_with_dict(block, &mut self.output, dictionary)
                .map_err(|e| error(format!("an LZ4 block does not decode: {e}")))?;
            self.output.truncate(n);
        }
        self.input_start += length;
        if frame.linked {
            self.window.extend_from_slice(&self.output);
            let excess = self.window.len().saturating_sub(WINDOW_BYTES);
            self.window.drain(..excess);
        }
        Ok(())
    }
}

/// Reads a frame descriptor (after the magic number): the frame and the bytes it took with the
/// magic number, or `None` when more input is needed.
fn read_descriptor(bytes: &[u8]) -> Result<Option<(Frame, usize)>, McapError> {
    let &[flags, block_descriptor, ..] = bytes else {
        return Ok(None);
    };
    if flags >> 6 != 1 {
        return Err(error(format!("LZ4 frame version {} is not 1", flags >> 6)));
    }
    if flags & 1 != 0 {
        return Err(error(
            "LZ4 frames with a preset dictionary are not supported".to_owned(),
        ));
    }
    let max_block_bytes = match (block_descriptor >> 4) & 7 {
        4 => 64 * 1024,
        5 => 256 * 1024,
        6 => 1024 * 1024,
        7 => 4 * 1024 * 1024,
        other => return Err(error(format!("LZ4 block size code {other} is not 4 to 7"))),
    };
    // FLG, BD, the content size if flagged, the header checksum.
    let descriptor = 2 + if flags & 0x08 != 0 { 8 } else { 0 } + 1;
    if bytes.len() < descriptor {
        return Ok(None);
    }
    let frame = Frame {
        linked: flags & 0x20 == 0,
        block_checksum: flags & 0x10 != 0,
        content_checksum: flags & 0x04 != 0,
        max_block_bytes,
    };
    Ok(Some((frame, 4 + descriptor)))
}

fn error(message: String) -> McapError {
    McapError::DecompressionError(message)
}

impl Decompressor for Lz4Chunks {
    fn next_read_size(&self) -> usize {
        0
    }

    fn decompress(&mut self, src: &[u8], dst: &mut [u8]) -> Result<DecompressResult, McapError> {
        // Compact before growing: what was decoded is not needed again.
        if self.input_start > 0 {
            self.input.drain(..self.input_start);
            self.input_start = 0;
        }
        self.input.extend_from_slice(src);
        let mut wrote = 0;
        while wrote < dst.len() {
            self.advance()?;
            let ready = &self.output[self.output_start..];
            if ready.is_empty() {
                break;
            }
            let n = ready.len().min(dst.len() - wrote);
            dst[wrote..wrote + n].copy_from_slice(&ready[..n]);
            self.output_start += n;
            wrote += n;
        }
        Ok(DecompressResult {
            consumed: src.len(),
            wrote,
        })
    }

    fn reset(&mut self) -> Result<(), McapError> {
        *self = Self::new();
        Ok(())
    }

    fn name(&self) -> &'static str {
        "lz4"
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A frame header: magic, FLG (version 1, `flags`), BD (64 KiB blocks), header checksum
    /// (not checked).
    fn header(flags: u8) -> Vec<u8> {
        let mut out = FRAME_MAGIC.to_le_bytes().to_vec();
        out.extend([0x40 | flags, 0x40, 0x00]);
        out
    }

    /// Block 1 stored: "abcdefgh". Block 2 compressed, linked: one sequence without literals
    /// copying 8 bytes from 8 back (the whole of block 1), then the literal "z". Decoded:
    /// "abcdefgh" + "abcdefghz".
    fn linked_frame() -> Vec<u8> {
        let mut frame = header(0x04); // linked blocks, content checksum present
        frame.extend((8u32 | 0x8000_0000).to_le_bytes());
        frame.extend(b"abcdefgh");
        let block = [0x04, 0x08, 0x00, 0x10, b'z'];
        frame.extend((block.len() as u32).to_le_bytes());
        frame.extend(block);
        frame.extend(0u32.to_le_bytes()); // end mark
        frame.extend([0xde, 0xad, 0xbe, 0xef]); // content checksum, skipped
        frame
    }

    /// Feeds `input` `step` bytes at a time into `dst` buffers of `out_step` bytes.
    fn decode(input: &[u8], step: usize, out_step: usize) -> Result<Vec<u8>, McapError> {
        let mut decoder = Lz4Chunks::new();
        let mut out = Vec::new();
        let mut dst = vec![0; out_step];
        for piece in input.chunks(step) {
            let result = decoder.decompress(piece, &mut dst)?;
            assert_eq!(result.consumed, piece.len());
            out.extend_from_slice(&dst[..result.wrote]);
        }
        loop {
            let result = decoder.decompress(&[], &mut dst)?;
            if result.wrote == 0 {
                return Ok(out);
            }
            out.extend_from_slice(&dst[..result.wrote]);
        }
    }

    #[test]
    fn a_linked_block_copies_from_the_one_before() -> Result<(), McapError> {
        for (step, out_step) in [(1, 1), (3, 2), (1000, 1000)] {
            let decoded = decode(&linked_frame(), step, out_step)?;
            assert_eq!(decoded, b"abcdefghabcdefghz", "{step}");
        }
        Ok(())
    }

    #[test]
    fn concatenated_and_skippable_frames_decode_in_order() -> Result<(), McapError> {
        let mut input = (SKIPPABLE_MAGIC + 3).to_le_bytes().to_vec();
        input.extend(3u32.to_le_bytes());
        input.extend(b"xyz");
        input.extend(linked_frame());
        input.extend(linked_frame());
        assert_eq!(decode(&input, 7, 5)?, b"abcdefghabcdefghz".repeat(2));
        Ok(())
    }

    #[test]
    fn an_independent_block_cannot_copy_from_the_one_before() {
        let mut frame = linked_frame();
        frame[4] |= 0x20; // FLG: independent blocks
        assert!(decode(&frame, 100, 100).is_err());
    }

    #[test]
    fn reset_starts_a_new_chunk() -> Result<(), McapError> {
        let mut decoder = Lz4Chunks::new();
        let mut dst = [0; 64];
        let frame = linked_frame();
        // Half a frame, then a reset: the next chunk decodes from its own start.
        decoder.decompress(&frame[..12], &mut dst)?;
        decoder.reset()?;
        let result = decoder.decompress(&frame, &mut dst)?;
        assert_eq!(&dst[..result.wrote], b"abcdefghabcdefghz");
        Ok(())
    }

    #[test]
    fn bad_frames_are_errors_not_panics() {
        let bad_magic = [1, 2, 3, 4, 0x40, 0x40, 0];
        assert!(decode(&bad_magic, 100, 100).is_err());
        assert!(
            decode(&header(0x01), 100, 100).is_err(),
            "preset dictionary"
        );
        let mut version = header(0);
        version[4] = 0x80;
        assert!(decode(&version, 100, 100).is_err(), "version 2");
        let mut too_big = header(0);
        too_big.extend((64 * 1024 + 1u32).to_le_bytes());
        assert!(decode(&too_big, 100, 100).is_err(), "block over 64 KiB");
        // Every truncation and every byte changed: an error or some output, never a panic.
        let frame = linked_frame();
        for end in 0..frame.len() {
            let _ = decode(&frame[..end], 3, 4);
        }
        for at in 0..frame.len() {
            for byte in [0x00, 0x0f, 0x80, 0xff] {
                let mut bad = frame.clone();
                bad[at] = byte;
                let _ = decode(&bad, 5, 3);
            }
        }
    }
}
