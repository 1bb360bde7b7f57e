//! Splits the program "tape" (bytes in chunks of any size) into numbered lines for the G-code
//! parser: CR, LF and CRLF each end one line (as grbl: a lone `\r` is a line end too), lines count
//! from 1, the last line needs no newline. Loader task (firmware idle) and host precheck.

/// Longest accepted line in bytes, without its line end.
pub const LINE_MAX: usize = 256;

/// Why a line was refused before it reached the parser.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LineError {
    /// More than [`LINE_MAX`] bytes before the line end.
    TooLong,
    /// Not valid UTF-8.
    NotUtf8,
}

impl LineError {
    /// The reason, worded like the parser's errors (`line N: <reason>`).
    pub const fn message(self) -> &'static str {
        match self {
            LineError::TooLong => "line too long",
            LineError::NotUtf8 => "not UTF-8",
        }
    }
}

/// Line assembler. `feed` and `finish` call the sink once per line with its number and its text
/// (or why it was refused); the sink returns `false` to stop, and then they return `false` too.
pub struct Lines {
    buf: [u8; LINE_MAX],
    len: usize,
    line_no: u32,
    /// The current line overflowed and was already reported; skip to its end.
    skipping: bool,
    /// The last byte was a `\r`: a `\n` right after it belongs to the same line end (CRLF).
    after_cr: bool,
    /// The length of the last line ended (its text stays in `buf` until the next byte).
    last: usize,
}

impl Default for Lines {
    fn default() -> Self {
        Self::new()
    }
}

impl Lines {
    pub const fn new() -> Self {
        Lines {
            buf: [0; LINE_MAX],
            len: 0,
            line_no: 0,
            skipping: false,
            after_cr: false,
            last: 0,
        }
    }

    /// Number of the last line handed to the sink.
    pub const fn line_no(&self) -> u32 {
        self.line_no
    }

    /// Takes the next bytes of the tape.
    pub fn feed(
        &mut self,
        bytes: &[u8],
        mut sink: impl FnMut(u32, Result<&str, LineError>) -> bool,
    ) -> bool {
        for &b in bytes {
            if let Some(ended) = self.push(b) {
                if !sink(ended.no, ended.error.map_or_else(|| Ok(self.text()), Err)) {
                    return false;
                }
            }
        }
        true
    }

    /// End of the tape: hands over a last line that had no newline.
    pub fn finish(&mut self, mut sink: impl FnMut(u32, Result<&str, LineError>) -> bool) -> bool {
        match self.end() {
            Some(ended) => sink(ended.no, ended.error.map_or_else(|| Ok(self.text()), Err)),
            None => true,
        }
    }

    /// Takes one byte of the tape; returns the line it ended, if it ended one (its text is then
    /// [`Lines::text`] until the next byte). A line too long is refused at once, at its 257th
    /// byte; the rest of it is skipped.
    pub fn push(&mut self, b: u8) -> Option<Ended> {
        let crlf = self.after_cr && b == b'\n';
        self.after_cr = b == b'\r';
        if crlf {
            // The `\n` of a CRLF: the `\r` already ended the line.
            None
        } else if b == b'\n' || b == b'\r' {
            if self.skipping {
                self.skipping = false;
                self.len = 0;
                None
            } else {
                Some(self.take())
            }
        } else if self.skipping {
            // Rest of an over-long line: already reported.
            None
        } else if let Some(slot) = self.buf.get_mut(self.len) {
            *slot = b;
            self.len += 1;
            self.last = 0;
            None
        } else {
            // Report at once: no need to read the rest of a runaway line first.
            self.skipping = true;
            self.len = 0;
            self.last = 0;
            self.line_no = self.line_no.saturating_add(1);
            Some(Ended {
                no: self.line_no,
                error: Some(LineError::TooLong),
            })
        }
    }

    /// End of the tape: the last line, if it had no newline.
    pub fn end(&mut self) -> Option<Ended> {
        if self.len == 0 || self.skipping {
            return None;
        }
        Some(self.take())
    }

    /// The text of the line [`Lines::push`] or [`Lines::end`] returned last (empty after a
    /// refused one).
    pub fn text(&self) -> &str {
        self.buf
            .get(..self.last)
            .and_then(|t| core::str::from_utf8(t).ok())
            .unwrap_or("")
    }

    fn take(&mut self) -> Ended {
        self.line_no = self.line_no.saturating_add(1);
        self.last = self.len;
        self.len = 0;
        let utf8 = self
            .buf
            .get(..self.last)
            .is_some_and(|t| core::str::from_utf8(t).is_ok());
        if !utf8 {
            self.last = 0;
        }
        Ended {
            no: self.line_no,
            error: (!utf8).then_some(LineError::NotUtf8),
        }
    }
}

/// A line [`Lines::push`] ended: its number, and why it was refused (None: its text is
/// [`Lines::text`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Ended {
    pub no: u32,
    pub error: Option<LineError>,
}

// Host tests run with `cargo test -p millac`.
#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::string::{String, ToString};
    use std::vec::Vec;

    fn split(chunks: &[&[u8]]) -> Vec<(u32, Result<String, LineError>)> {
        let mut v = Vec::new();
        let mut l = Lines::new();
        let mut sink = |n: u32, t: Result<&str, LineError>| {
            v.push((n, t.map(|s| s.to_string())));
            true
        };
        for c in chunks {
            l.feed(c, &mut sink);
        }
        l.finish(&mut sink);
        v
    }

    #[test]
    fn crlf_chunks_and_last_line() {
        let v = split(&[b"G21\r", b"\nG1 X1\n\nM", b"2"]);
        let t: Vec<_> = v.iter().map(|(n, t)| (*n, t.clone().unwrap())).collect();
        assert_eq!(
            t,
            [
                (1, "G21".into()),
                (2, "G1 X1".into()),
                (3, String::new()),
                (4, "M2".into())
            ]
        );
    }

    /// CR, LF and CRLF each end exactly one line, also split across chunks (grbl's rule); LF CR
    /// is two line ends.
    #[test]
    fn every_line_end() {
        let texts = |v: Vec<(u32, Result<String, LineError>)>| -> Vec<(u32, String)> {
            v.into_iter().map(|(n, t)| (n, t.unwrap())).collect()
        };
        let lone_cr = texts(split(&[b"G0 Z0.05\rX0.05 Y0.05\r"]));
        assert_eq!(lone_cr, [(1, "G0 Z0.05".into()), (2, "X0.05 Y0.05".into())]);
        let want: Vec<(u32, String)> = vec![(1, "A".into()), (2, "B".into()), (3, "C".into())];
        for sep in [&b"\r"[..], b"\n", b"\r\n"] {
            let whole = [b"A", sep, b"B", sep, b"C", sep].concat();
            assert_eq!(texts(split(&[&whole])), want, "{sep:?}");
            // Byte by byte: a CRLF split between chunks is still one line end.
            let bytes: Vec<&[u8]> = whole.chunks(1).collect();
            assert_eq!(texts(split(&bytes)), want, "{sep:?} byte by byte");
        }
        let lfcr = texts(split(&[b"A\n\rB"]));
        assert_eq!(lfcr, [(1, "A".into()), (2, String::new()), (3, "B".into())]);
    }

    #[test]
    fn limits() {
        let ok = [b'X'; LINE_MAX];
        let long = [b'Y'; LINE_MAX + 1];
        let v = split(&[&ok, b"\r\n", &long, b"\r\n", b"\xff\n"]);
        assert_eq!(v[0].0, 1);
        assert!(v[0].1.is_ok());
        assert_eq!(v[1], (2, Err(LineError::TooLong)));
        assert_eq!(v[2], (3, Err(LineError::NotUtf8)));
        // A runaway line is reported once, as soon as it overflows.
        let runaway = [b'Z'; 3 * LINE_MAX];
        let v = split(&[&runaway, b"\nG0\n"]);
        assert_eq!(v, [(1, Err(LineError::TooLong)), (2, Ok("G0".into()))]);
    }
}
