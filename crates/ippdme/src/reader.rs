//! A bounded line reader: lines end with LF (a CR before it is dropped); a line longer than the
//! limit is reported as [`ReadLine::TooLong`] without ever holding more than the limit in memory.
//!
//! Entry point: [`LineReader::read_line`].

use std::io::{self, Read};

/// The contract's limit for one line (64 KiB).
pub const MAX_LINE: usize = 64 * 1024;

/// What one read produced.
#[derive(Debug, PartialEq, Eq)]
pub enum ReadLine {
    /// A complete line without its CR LF / LF.
    Line(Vec<u8>),
    /// More than the limit arrived without an end of line. The reader is not usable afterwards.
    TooLong,
    /// The peer closed the connection (a partial last line is dropped).
    Eof,
}

/// Reads lines from `R` with a fixed-size buffer.
pub struct LineReader<R> {
    inner: R,
    buf: Vec<u8>,
    start: usize,
    end: usize,
    limit: usize,
}

impl<R: Read> LineReader<R> {
    /// A reader with the protocol's line limit.
    pub fn new(inner: R) -> Self {
        Self::with_limit(inner, MAX_LINE)
    }

    /// A reader refusing lines longer than `limit` bytes.
    pub fn with_limit(inner: R, limit: usize) -> Self {
        LineReader { inner, buf: vec![0; limit + 2], start: 0, end: 0, limit }
    }

    /// The underlying reader.
    pub fn get_ref(&self) -> &R {
        &self.inner
    }

    /// Whether a complete line is already buffered (no read needed to return it).
    pub fn has_buffered_line(&self) -> bool {
        self.buf[self.start..self.end].contains(&b'\n')
    }

    /// The next line. I/O errors (including read timeouts) are passed through; after a timeout
    /// the partial line stays buffered and the call can be repeated.
    pub fn read_line(&mut self) -> io::Result<ReadLine> {
        loop {
            if let Some(k) = self.buf[self.start..self.end].iter().position(|&b| b == b'\n') {
                let mut line = self.buf[self.start..self.start + k].to_vec();
                self.start += k + 1;
                if line.last() == Some(&b'\r') {
                    line.pop();
                }
                if line.len() > self.limit {
                    return Ok(ReadLine::TooLong);
                }
                return Ok(ReadLine::Line(line));
            }
            if self.end - self.start > self.limit {
                return Ok(ReadLine::TooLong);
            }
            if self.start > 0 {
                self.buf.copy_within(self.start..self.end, 0);
                self.end -= self.start;
                self.start = 0;
            }
            if self.end == self.buf.len() {
                return Ok(ReadLine::TooLong);
            }
            let n = self.inner.read(&mut self.buf[self.end..])?;
            if n == 0 {
                return Ok(ReadLine::Eof);
            }
            self.end += n;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splits_crlf_and_lf_lines() {
        let mut r = LineReader::new(&b"00001 A()\r\n00002 B()\nrest"[..]);
        assert_eq!(r.read_line().unwrap(), ReadLine::Line(b"00001 A()".to_vec()));
        assert_eq!(r.read_line().unwrap(), ReadLine::Line(b"00002 B()".to_vec()));
        assert_eq!(r.read_line().unwrap(), ReadLine::Eof);
    }

    #[test]
    fn a_long_line_is_refused_with_bounded_memory() {
        let data = vec![b'x'; 1 << 20];
        let mut r = LineReader::with_limit(&data[..], 1000);
        assert_eq!(r.read_line().unwrap(), ReadLine::TooLong);
        assert!(r.buf.len() <= 1002);
        let mut ok = vec![b'y'; 1000];
        ok.push(b'\n');
        let mut r = LineReader::with_limit(&ok[..], 1000);
        assert_eq!(r.read_line().unwrap(), ReadLine::Line(vec![b'y'; 1000]));
    }
}
