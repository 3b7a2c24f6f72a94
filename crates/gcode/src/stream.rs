//! Re-orienting a program of any size in constant memory.
//!
//! A program is cut into pieces of complete lines (about [`PIECE_BYTES`] each). Each piece is
//! tokenised and its parameters and expressions evaluated with the settings of the pieces before
//! it; then the same [`Rewriter`] that [`Program::transform`] uses rewrites it, carrying the
//! modal state, the last written positions and the incremental accumulators from piece to piece.
//! So the output is byte for byte what the in-memory transform gives, errors keep the line and
//! column of the whole program, and only a few pieces are ever in memory.
//!
//! Entry points:
//! - [`transform_stream`]: read a `BufRead`, write a `Write`. A reader thread reads, tokenises
//!   and evaluates the next pieces (two deep) while a rewriting thread rewrites the current one
//!   and the caller's thread writes the one before: the work of three stages on the cores there
//!   are, in order.
//! - [`StreamTransform`]: the same, pushed text by text from the caller's own loop.
//!
//! The first thing that cannot be executed or re-oriented, in program order, is the error;
//! nothing after it is written (callers write into an atomic file and drop it on error).

use crate::expr::Params;
use crate::rewrite::Rewriter;
use crate::{GcodeError, Program, TransformOptions};
use std::io::{BufRead, Write};
use std::sync::mpsc::{sync_channel, Receiver, Sender, SyncSender};
use truepos_math::Transform3;

/// Bytes of text per piece.
pub const PIECE_BYTES: usize = 1 << 18;

/// What a streamed rewrite did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StreamSummary {
    /// Lines of the program.
    pub lines: usize,
}

/// A streamed rewrite that failed: the program (located), reading it, or writing the output.
#[derive(Debug, thiserror::Error)]
pub enum StreamError {
    /// The program is not valid or not supported (located error).
    #[error(transparent)]
    Gcode(#[from] GcodeError),
    /// The program could not be read.
    #[error("cannot read the program: {0}")]
    Read(#[source] std::io::Error),
    /// The output could not be written.
    #[error("cannot write the output: {0}")]
    Write(#[source] std::io::Error),
}

/// A tokenised, evaluated piece and the result of its check (line relative to the piece).
struct Piece {
    program: Program,
    checked: Result<(), GcodeError>,
}

/// Tokenises pieces in order, carrying the parameters set so far.
#[derive(Default)]
struct PieceParser {
    params: Params,
    started: bool,
}

impl PieceParser {
    fn parse(&mut self, text: String, reuse: Option<Program>) -> Piece {
        let (program, checked) = Program::parse_piece(text, &mut self.params, !self.started, reuse);
        self.started = true;
        Piece { program, checked }
    }
}

/// Rewrite `piece` (lines up to its first failed check) and report that check, located in the
/// whole program.
fn rewrite_piece(rw: &mut Rewriter, piece: &Piece, out: &mut String) -> Result<(), GcodeError> {
    let base = rw.lines_done();
    let upto = match &piece.checked {
        Ok(()) => piece.program.lines.len(),
        Err(e) => e.line() - 1,
    };
    rw.rewrite_lines(&piece.program, upto, out)?;
    piece.checked.clone().map_err(|e| e.shifted(base))
}

/// Text that is not UTF-8: an error at the line and column (in characters) of the first bad
/// byte; `before` lines precede `bytes`.
fn not_utf8(bytes: &[u8], valid_up_to: usize, before: usize) -> GcodeError {
    let ok = &bytes[..valid_up_to];
    let line_start = memchr::memrchr(b'\n', ok).map_or(0, |p| p + 1);
    let column = std::str::from_utf8(&ok[line_start..]).map_or(1, |s| s.chars().count() + 1);
    GcodeError::Unsupported {
        line: before + memchr::memchr_iter(b'\n', ok).count() + 1,
        column,
        message: "not valid UTF-8 text: not a G-code file".into(),
    }
}

/// A streamed rewrite driven by the caller: [`push`](Self::push) text as it comes (any
/// split, even inside a line), [`finish`](Self::finish) at the end. Only complete lines are
/// rewritten at each push; the rest waits for the next one.
pub struct StreamTransform {
    parser: PieceParser,
    rewriter: Rewriter,
    carry: String,
}

impl StreamTransform {
    /// A rewriter applying `new_from_old` (old program frame to new frame, mm) with `opts`.
    pub fn new(new_from_old: &Transform3, opts: &TransformOptions) -> Self {
        Self {
            parser: PieceParser::default(),
            rewriter: Rewriter::new(new_from_old, opts),
            carry: String::new(),
        }
    }

    /// Append `text`; the complete lines so far are rewritten into `out`.
    pub fn push(&mut self, text: &str, out: &mut String) -> Result<(), GcodeError> {
        self.carry.push_str(text);
        let Some(nl) = memchr::memrchr(b'\n', self.carry.as_bytes()) else { return Ok(()) };
        let rest = self.carry.split_off(nl + 1);
        let piece = self.parser.parse(std::mem::replace(&mut self.carry, rest), None);
        rewrite_piece(&mut self.rewriter, &piece, out)
    }

    /// Rewrite what is left (a last line without a line end) and return the number of lines.
    pub fn finish(mut self, out: &mut String) -> Result<StreamSummary, GcodeError> {
        if !self.carry.is_empty() {
            let piece = self.parser.parse(std::mem::take(&mut self.carry), None);
            rewrite_piece(&mut self.rewriter, &piece, out)?;
        }
        Ok(StreamSummary { lines: self.rewriter.lines_done() })
    }
}

/// Rewrite the program read from `input` through `new_from_old` (mm) into `output`, piece by
/// piece (see the module docs): byte for byte what [`Program::transform`] gives, in constant
/// memory. On an error, what was written before it is an incomplete program: write into a file
/// that is discarded on error.
///
/// Three threads: one reads and tokenises, one rewrites, and the caller's writes the output
/// (its system calls overlap the rewriting of the next piece). On an error the other threads
/// are not waited for (on a pipe the reader may be blocked in a read); they end at their next
/// hand-over.
pub fn transform_stream<R, W>(
    input: R,
    mut output: W,
    new_from_old: &Transform3,
    opts: &TransformOptions,
) -> Result<StreamSummary, StreamError>
where
    R: BufRead + Send + 'static,
    W: Write,
{
    let (tx, rx) = sync_channel::<Result<Piece, StreamError>>(2);
    // Finished pieces go back to the reader, which reuses their memory.
    let (back_tx, back_rx) = std::sync::mpsc::channel::<Program>();
    let reader = std::thread::Builder::new()
        .name("truepos-gcode-reader".into())
        .spawn(move || read_pieces(input, tx, back_rx))
        .map_err(StreamError::Read)?;
    // Rewritten text to the caller, and its buffers back once written.
    let (text_tx, text_rx) = sync_channel::<Result<String, StreamError>>(2);
    let (free_tx, free_rx) = std::sync::mpsc::channel::<String>();
    let rw = Rewriter::new(new_from_old, opts);
    let rewriter = std::thread::Builder::new()
        // (Thread names are cut to 15 bytes in profilers: "truepos-gcode-r" is the reader.)
        .name("truepos-rewriter".into())
        .spawn(move || rewrite_pieces(rw, rx, back_tx, text_tx, free_rx))
        .map_err(StreamError::Read)?;
    for text in text_rx.iter() {
        let text = text?;
        output.write_all(text.as_bytes()).map_err(StreamError::Write)?;
        let _ = free_tx.send(text);
    }
    output.flush().map_err(StreamError::Write)?;
    // The channel closed: the rewriter has returned, after the reader's channel closed. A
    // stage that panicked closed its channel early: its panic is the caller's (not a shorter
    // output taken for the whole).
    let lines = match rewriter.join() {
        Ok(lines) => lines,
        Err(panic) => std::panic::resume_unwind(panic),
    };
    if let Err(panic) = reader.join() {
        std::panic::resume_unwind(panic);
    }
    Ok(StreamSummary { lines })
}

/// The rewriting thread: each piece rewritten into a buffer (one the caller has written and
/// handed back, when there is one) and sent on, in order; the first error is sent instead of
/// its piece's text, and ends the rewriting. Returns the count of lines.
fn rewrite_pieces(
    mut rw: Rewriter,
    pieces: Receiver<Result<Piece, StreamError>>,
    back: Sender<Program>,
    texts: SyncSender<Result<String, StreamError>>,
    free: Receiver<String>,
) -> usize {
    for piece in pieces.iter() {
        let piece = match piece {
            Ok(p) => p,
            Err(e) => {
                let _ = texts.send(Err(e));
                break;
            }
        };
        let mut out =
            free.try_recv().unwrap_or_else(|_| String::with_capacity(PIECE_BYTES + PIECE_BYTES / 4));
        out.clear();
        if let Err(e) = rewrite_piece(&mut rw, &piece, &mut out) {
            let _ = texts.send(Err(e.into()));
            break;
        }
        let _ = back.send(piece.program);
        if texts.send(Ok(out)).is_err() {
            break;
        }
    }
    rw.lines_done()
}

/// The reader thread: pieces of complete lines, tokenised and evaluated, in order. Stops after
/// a piece whose check failed (nothing after it is rewritten), at an error, or when the
/// receiver is gone.
fn read_pieces<R: BufRead>(
    mut input: R,
    tx: SyncSender<Result<Piece, StreamError>>,
    back: std::sync::mpsc::Receiver<Program>,
) {
    let mut parser = PieceParser::default();
    let mut carry: Vec<u8> = Vec::new();
    let mut lines_before = 0usize;
    loop {
        let mut reuse = back.try_recv().ok();
        let mut buf = std::mem::take(&mut carry);
        if let Some(old) = &mut reuse {
            // The text of a finished piece: its allocation, with the carried part first.
            let mut text = std::mem::take(&mut old.source).into_bytes();
            text.clear();
            text.extend_from_slice(&buf);
            buf = text;
        }
        buf.reserve(PIECE_BYTES);
        let mut eof = false;
        // Read up to `want` bytes, then cut after the last line end (everything at the end of
        // the input). The carried part holds no line end: only what is read after it is
        // searched. A line longer than a piece reads on, a piece's size at a time.
        let mut want = PIECE_BYTES;
        let mut searched = buf.len();
        let cut = loop {
            while buf.len() < want {
                let avail = match input.fill_buf() {
                    Ok(b) => b,
                    Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
                    Err(e) => {
                        let _ = tx.send(Err(StreamError::Read(e)));
                        return;
                    }
                };
                if avail.is_empty() {
                    eof = true;
                    break;
                }
                // Up to the piece's size (the reader's buffer may hold more: it waits there).
                let n = avail.len().min(want - buf.len());
                buf.extend_from_slice(&avail[..n]);
                input.consume(n);
            }
            if eof {
                break buf.len();
            }
            if let Some(p) = memchr::memrchr(b'\n', &buf[searched..]) {
                break searched + p + 1;
            }
            searched = buf.len();
            want = buf.len() + PIECE_BYTES;
        };
        carry = buf.split_off(cut);
        if !buf.is_empty() {
            let text = match String::from_utf8(buf) {
                Ok(t) => t,
                Err(e) => {
                    let at = e.utf8_error().valid_up_to();
                    let _ = tx.send(Err(not_utf8(e.as_bytes(), at, lines_before).into()));
                    return;
                }
            };
            let piece = parser.parse(text, reuse);
            lines_before += piece.program.lines.len();
            let failed = piece.checked.is_err();
            if tx.send(Ok(piece)).is_err() || failed {
                return;
            }
        }
        if eof {
            return;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use truepos_math::types::{rx, rz};
    use truepos_math::Vector3;

    fn stream(src: &str, t: &Transform3, opts: &TransformOptions) -> Result<String, StreamError> {
        let mut out = Vec::new();
        transform_stream(std::io::Cursor::new(src.as_bytes().to_vec()), &mut out, t, opts)?;
        Ok(String::from_utf8(out).unwrap())
    }

    #[test]
    fn utf8_errors_are_located() {
        let mut b = b"G0 X1 Y1 Z1\nG1 X2 (caf\xc3\xa9) Y".to_vec();
        b.extend_from_slice(b"\xff\n");
        let mut out = Vec::new();
        let e =
            transform_stream(std::io::Cursor::new(b), &mut out, &Transform3::identity(), &Default::default())
                .unwrap_err();
        let StreamError::Gcode(e) = e else { panic!("{e}") };
        assert_eq!((e.line(), e.column()), (2, 15), "{e}");
    }

    /// CR-only line ends (classic Mac OS) are refused at the first CR followed by more text,
    /// in memory and streamed; before, the program read as one block and was rewritten wrong
    /// (the first motion took the last X). CRLF and a doubled CR before the LF are line ends.
    #[test]
    fn cr_only_line_ends_are_refused_with_their_place() {
        let shift = Transform3::new(1.0, rz(0.0), Vector3::new(1.0, 0.0, 0.0));
        for src in ["G90\rG0 X1 Y2 Z3\rG1 X10 Y10 Z0 F100\r", "G90\rG0 X1 Y2 Z3\r\n"] {
            let e = Program::parse(src).check().unwrap_err();
            assert_eq!((e.line(), e.column()), (1, 4), "{e}");
            assert!(e.to_string().contains("CR-only line ends"), "{e}");
            let StreamError::Gcode(e) = stream(src, &shift, &Default::default()).unwrap_err() else {
                panic!()
            };
            assert_eq!((e.line(), e.column()), (1, 4), "{e}");
        }
        let e = Program::parse("G90\nG0 X1 (a) \r Y2\n").check().unwrap_err();
        assert_eq!((e.line(), e.column()), (2, 11), "{e}");
        for ok in ["G90\r\nG0 X1 Y2 Z3\r\n", "G90\r\r\nG0 X1 Y0 Z0\r \r\n", "G90 \r\nG0 X1 Y0 Z0"] {
            Program::parse(ok).check().unwrap();
            assert!(stream(ok, &shift, &Default::default()).unwrap().contains("X2"), "{ok:?}");
        }
    }

    /// Pieces split anywhere (inside lines, inside multi-byte characters' lines) give the
    /// in-memory result; a byte-order mark is accepted at the start only.
    #[test]
    fn pushed_pieces_give_the_in_memory_result() {
        let src = "\u{feff}%\n#1=2\nG21 G90 G17\nG0 X[#1+8] Y0 Z#1 (keep (this) X99)\r\nG1 X20 F100 ; é\nG91 X1 Y1\nG90 G2 X30 Y10 I5 J5\nM30";
        let t = Transform3::new(1.0001, rz(0.3), Vector3::new(5.0, -2.0, 1.0));
        let opts = TransformOptions::default();
        let want = Program::parse(src).transform(&t, &opts).unwrap();
        for step in [1, 2, 3, 7, 1000] {
            let mut st = StreamTransform::new(&t, &opts);
            let mut out = String::new();
            let chars: Vec<char> = src.chars().collect();
            for c in chars.chunks(step) {
                st.push(&c.iter().collect::<String>(), &mut out).unwrap();
            }
            let sum = st.finish(&mut out).unwrap();
            assert_eq!(out, want, "step {step}");
            assert_eq!(sum.lines, Program::parse(src).lines.len());
        }
        assert_eq!(stream(src, &t, &opts).unwrap(), want);
        // A byte-order mark after the first piece is not G-code.
        let mut st = StreamTransform::new(&Transform3::identity(), &opts);
        let mut out = String::new();
        st.push("G0 X1 Y1 Z1\n", &mut out).unwrap();
        let e = st.push("\u{feff}G1 X2\n", &mut out).unwrap_err();
        assert_eq!((e.line(), e.column()), (2, 1), "{e}");
    }

    /// Errors in later pieces keep their line in the whole program, and the first error in
    /// program order wins, whether it is a check (malformed word) or a refusal of the rewrite.
    #[test]
    fn errors_keep_their_place_in_the_whole_program() {
        let mut src = String::from("G21 G90\nG0 X0 Y0 Z0\n");
        for i in 0..200_000 {
            src.push_str(&format!("G1 X{}.5 Y{}\n", i % 1000, i % 7));
        }
        assert!(src.len() > 2 * PIECE_BYTES);
        let n = 200_002;
        let t = Transform3::rigid(rx(0.2), Vector3::zeros());
        let opts = TransformOptions::default();
        for (tail, col) in [("G1 X1.2.3\n", 4), ("G2 X1 Y1 I1 J0\n", 10)] {
            let bad = format!("{src}{tail}G1 Xabc\n");
            let e = stream(&bad, &t, &opts).unwrap_err();
            let StreamError::Gcode(e) = e else { panic!("{e}") };
            assert_eq!((e.line(), e.column()), (n + 1, col), "{tail}: {e}");
            let e = Program::parse(&bad).transform(&t, &opts).unwrap_err();
            assert_eq!((e.line(), e.column()), (n + 1, col), "{tail}: {e}");
        }
    }

    /// A line longer than a piece (several pieces long, at the start, in the middle and at the
    /// end without a line end) is read on until its end, and the output is the in-memory one.
    #[test]
    fn lines_longer_than_a_piece_are_read_whole() {
        let long = format!("({})", "x".repeat(3 * PIECE_BYTES + 17));
        let mut src = format!("{long}\nG0 X1 Y2 Z3\n");
        for i in 0..50_000 {
            src.push_str(&format!("G1 X{}.25 Y{}\n", i % 100, i % 7));
        }
        src.push_str(&format!("G1 X5 {long}\r\nG1 Y1\n{long}"));
        let t = Transform3::new(1.0001, rz(0.3), Vector3::new(5.0, -2.0, 1.0));
        let opts = TransformOptions::default();
        let want = Program::parse(&src).transform(&t, &opts).unwrap();
        assert_eq!(stream(&src, &t, &opts).unwrap(), want);
    }

    #[test]
    fn read_and_write_failures_are_reported() {
        struct Broken;
        impl std::io::Read for Broken {
            fn read(&mut self, _: &mut [u8]) -> std::io::Result<usize> {
                Err(std::io::Error::other("disk on fire"))
            }
        }
        let mut out = Vec::new();
        let r = std::io::BufReader::new(Broken);
        let e = transform_stream(r, &mut out, &Transform3::identity(), &Default::default()).unwrap_err();
        assert!(matches!(e, StreamError::Read(_)) && e.to_string().contains("disk on fire"), "{e}");
        struct Full;
        impl Write for Full {
            fn write(&mut self, _: &[u8]) -> std::io::Result<usize> {
                Err(std::io::Error::other("no space"))
            }
            fn flush(&mut self) -> std::io::Result<()> {
                Ok(())
            }
        }
        let e = transform_stream(
            std::io::Cursor::new(b"G0 X1 Y1 Z1\n".to_vec()),
            Full,
            &Transform3::identity(),
            &Default::default(),
        )
        .unwrap_err();
        assert!(matches!(e, StreamError::Write(_)), "{e}");
    }
}
