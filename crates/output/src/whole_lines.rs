//! Records written whole: a process that ends at once on a signal never leaves a file ending
//! in a torn line (`frames.jsonl`).
//!
//! [`WholeLines`] holds a lock while it writes a batch of whole lines; [`stop_records`] takes
//! that lock for good, so that once it returns no record is being written and none is started.

use std::io::Write;
use std::sync::{Mutex, PoisonError};

/// Held while a batch of whole lines is written, and taken for good by [`stop_records`].
static WRITING: Mutex<()> = Mutex::new(());

/// Waits for the record being written, if any, and stops every [`WholeLines`] writer of this
/// process for good (their next write blocks): for a process about to end on a signal.
pub fn stop_records() {
    let writing = WRITING.lock().unwrap_or_else(PoisonError::into_inner);
    // Never released: the process ends with the lock held.
    std::mem::forget(writing);
}

/// A writer of whole lines: text is kept until its line ends, and each batch of whole lines
/// goes to the file in one write that [`stop_records`] cannot cut short. A line not ended when
/// the writer is dropped is not written.
#[derive(Debug)]
pub struct WholeLines<W: Write> {
    inner: W,
    pending: Vec<u8>,
}

impl<W: Write> WholeLines<W> {
    /// Whole lines to `inner`.
    pub fn new(inner: W) -> Self {
        Self {
            inner,
            pending: Vec::new(),
        }
    }

    /// Writes the whole lines pending.
    fn write_lines(&mut self) -> std::io::Result<()> {
        let Some(end) = self.pending.iter().rposition(|&b| b == b'\n') else {
            return Ok(());
        };
        let _writing = WRITING.lock().unwrap_or_else(PoisonError::into_inner);
        self.inner.write_all(&self.pending[..=end])?;
        self.inner.flush()?;
        self.pending.drain(..=end);
        Ok(())
    }
}

impl<W: Write> Write for WholeLines<W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.pending.extend_from_slice(buf);
        if buf.contains(&b'\n') {
            self.write_lines()?;
        }
        Ok(buf.len())
    }

    /// Writes the whole lines pending; a line not yet ended stays pending.
    fn flush(&mut self) -> std::io::Result<()> {
        self.write_lines()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn whole_lines_are_written_and_a_torn_one_never() -> std::io::Result<()> {
        let mut file = Vec::new();
        {
            let mut lines = WholeLines::new(&mut file);
            lines.write_all(b"{\"frame\": 0")?;
            lines.write_all(b"}\n{\"fra")?;
            lines.flush()?;
            lines.write_all(b"me\": 1")?;
        }
        assert_eq!(file, b"{\"frame\": 0}\n");
        Ok(())
    }
}
