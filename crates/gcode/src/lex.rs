//! Tokeniser: splits each line into tokens that tile it exactly.
//!
//! Token kinds: whitespace, comments (`( … )` and `; …`), words (a letter and a number:
//! `G1`, `X-12.5`, `N100`, `O1000`), `%`, malformed words (a letter followed by a number that
//! does not parse, such as `X1.2.3`), and anything else kept verbatim (`#1=2`, `X[#1+2]`,
//! `/` block delete, …).

use crate::{Line, Program};

#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TokenKind {
    Whitespace,
    /// `( … )`; `closed` is false when the line ends before `)`.
    ParenComment {
        closed: bool,
    },
    /// `; …` to the end of the line.
    SemicolonComment,
    /// A letter (upper-cased here) and its value. `decimals` is the number of digits written
    /// after the decimal point (`None` when there is no point).
    Word {
        letter: u8,
        value: f64,
        decimals: Option<u8>,
    },
    /// A letter followed by something that looks like a number but is not one.
    Malformed {
        letter: u8,
    },
    Percent,
    /// Anything else, verbatim.
    Other,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Token {
    pub kind: TokenKind,
    pub start: usize,
    pub end: usize,
}

impl Token {
    /// The word's letter and value, if this is a word.
    pub fn word(&self) -> Option<(u8, f64)> {
        match self.kind {
            TokenKind::Word { letter, value, .. } => Some((letter, value)),
            _ => None,
        }
    }
}

pub(crate) fn parse(source: &str) -> Program {
    // Large programs are tokenised in parallel chunks split at line ends.
    const CHUNK: usize = 1 << 20;
    let b = source.as_bytes();
    if b.len() <= 2 * CHUNK {
        let (tokens, lines) = parse_range(source, 0, b.len());
        return Program { source: source.to_string(), tokens, lines };
    }
    let mut bounds = vec![0];
    let mut at = CHUNK;
    while at < b.len() {
        match memchr_nl(&b[at..]) {
            Some(p) => {
                bounds.push(at + p + 1);
                at = at + p + 1 + CHUNK;
            }
            None => break,
        }
    }
    bounds.push(b.len());
    bounds.dedup();
    use rayon::prelude::*;
    let parts: Vec<(Vec<Token>, Vec<Line>)> =
        bounds.par_windows(2).map(|w| parse_range(source, w[0], w[1])).collect();
    let n_tok = parts.iter().map(|p| p.0.len()).sum();
    let n_lines = parts.iter().map(|p| p.1.len()).sum();
    let mut tokens = Vec::with_capacity(n_tok);
    let mut lines = Vec::with_capacity(n_lines);
    for (t, l) in parts {
        let base = tokens.len();
        lines.extend(l.into_iter().map(|mut line| {
            line.tokens = line.tokens.start + base..line.tokens.end + base;
            line
        }));
        tokens.extend(t);
    }
    Program { source: source.to_string(), tokens, lines }
}

/// Tokenise the lines in `source[from..to]` (`from` at a line start, `to` after a line end or
/// at the end of the source). Offsets are absolute.
fn parse_range(source: &str, from: usize, to: usize) -> (Vec<Token>, Vec<Line>) {
    let b = &source.as_bytes()[..to];
    let mut tokens = Vec::with_capacity((to - from) / 4);
    let mut lines = Vec::with_capacity((to - from) / 16 + 1);
    let mut pos = from;
    while pos < b.len() {
        let nl = memchr_nl(&b[pos..]).map(|p| pos + p);
        let (end, next) = match nl {
            Some(n) if n > pos && b[n - 1] == b'\r' => (n - 1, n + 1),
            Some(n) => (n, n + 1),
            None => (b.len(), b.len()),
        };
        let t0 = tokens.len();
        lex_line(source, pos, end, &mut tokens);
        lines.push(Line { start: pos, end, next, tokens: t0..tokens.len() });
        pos = next;
    }
    (tokens, lines)
}

#[inline]
fn memchr_nl(b: &[u8]) -> Option<usize> {
    memchr::memchr(b'\n', b)
}

fn lex_line(src: &str, start: usize, end: usize, out: &mut Vec<Token>) {
    let b = src.as_bytes();
    let mut i = start;
    while i < end {
        let c = b[i];
        let s = i;
        let kind = match c {
            b' ' | b'\t' | b'\r' => {
                while i < end && matches!(b[i], b' ' | b'\t' | b'\r') {
                    i += 1;
                }
                TokenKind::Whitespace
            }
            b'(' => {
                i += 1;
                while i < end && b[i] != b')' {
                    i += 1;
                }
                let closed = i < end;
                if closed {
                    i += 1;
                }
                TokenKind::ParenComment { closed }
            }
            b';' => {
                i = end;
                TokenKind::SemicolonComment
            }
            b'%' => {
                i += 1;
                TokenKind::Percent
            }
            c if c.is_ascii_alphabetic() => {
                i += 1;
                match lex_number(b, i, end) {
                    Some((n_end, value, decimals, clean)) => {
                        i = n_end;
                        if clean {
                            TokenKind::Word { letter: c.to_ascii_uppercase(), value, decimals }
                        } else {
                            TokenKind::Malformed { letter: c.to_ascii_uppercase() }
                        }
                    }
                    None => {
                        // A letter without a number: keep the letter with what follows up to the
                        // next space, comment or letter (e.g. `X#1`, `X[1+2]`), verbatim.
                        let mut depth = 0i32;
                        while i < end {
                            let d = b[i];
                            if d == b'[' {
                                depth += 1;
                            } else if d == b']' {
                                depth -= 1;
                            } else if depth <= 0
                                && (d == b' '
                                    || d == b'\t'
                                    || d == b'('
                                    || d == b';'
                                    || d.is_ascii_alphabetic())
                            {
                                break;
                            }
                            i += 1;
                        }
                        TokenKind::Other
                    }
                }
            }
            _ => {
                // Verbatim run up to the next space, comment or letter. Multi-byte UTF-8
                // characters are consumed whole.
                i += 1;
                while i < end && !src.is_char_boundary(i) {
                    i += 1;
                }
                while i < end {
                    let d = b[i];
                    if d == b' '
                        || d == b'\t'
                        || d == b'('
                        || d == b';'
                        || d == b'%'
                        || d.is_ascii_alphabetic()
                    {
                        break;
                    }
                    i += 1;
                    while i < end && !src.is_char_boundary(i) {
                        i += 1;
                    }
                }
                TokenKind::Other
            }
        };
        out.push(Token { kind, start: s, end: i });
    }
}

/// A number after a word letter: `[+-]? (digits [. digits*] | . digits)`. Returns the end, the
/// value, the count of decimals, and whether the number is clean (not followed by more digits or
/// points, as in `1.2.3` or `1..2`, which make the word malformed).
fn lex_number(b: &[u8], start: usize, end: usize) -> Option<(usize, f64, Option<u8>, bool)> {
    let mut i = start;
    if i < end && (b[i] == b'+' || b[i] == b'-') {
        i += 1;
    }
    let int_start = i;
    while i < end && b[i].is_ascii_digit() {
        i += 1;
    }
    let n_int = i - int_start;
    let mut decimals = None;
    if i < end && b[i] == b'.' {
        i += 1;
        let f0 = i;
        while i < end && b[i].is_ascii_digit() {
            i += 1;
        }
        decimals = Some((i - f0).min(255) as u8);
    }
    let n_frac = decimals.unwrap_or(0) as usize;
    if n_int == 0 && n_frac == 0 {
        if i > start {
            // A sign or a lone point with no digit: malformed.
            let mut j = i;
            while j < end && (b[j].is_ascii_digit() || b[j] == b'.' || b[j] == b'+' || b[j] == b'-') {
                j += 1;
            }
            return Some((j, f64::NAN, None, false));
        }
        return None;
    }
    // Trailing digits or points (e.g. `1.2.3`) make the word malformed; consume them.
    let mut j = i;
    while j < end && (b[j].is_ascii_digit() || b[j] == b'.') {
        j += 1;
    }
    if j > i {
        return Some((j, f64::NAN, None, false));
    }
    // Safe: the range holds only ASCII sign, digits and one point.
    let text = std::str::from_utf8(&b[start..i]).ok()?;
    let value: f64 = text.parse().ok()?;
    Some((i, value, decimals, true))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn kinds(s: &str) -> Vec<(TokenKind, String)> {
        let p = parse(s);
        p.tokens.iter().map(|t| (t.kind, s[t.start..t.end].to_string())).collect()
    }

    #[test]
    fn tokens_of_a_typical_line() {
        let k = kinds("N10 G01 X-1.50 y.5 (MSG,Measure SOMaC) ; end");
        let texts: Vec<&str> = k.iter().map(|k| k.1.as_str()).collect();
        assert_eq!(
            texts,
            vec!["N10", " ", "G01", " ", "X-1.50", " ", "y.5", " ", "(MSG,Measure SOMaC)", " ", "; end"]
        );
        assert_eq!(k[4].0, TokenKind::Word { letter: b'X', value: -1.5, decimals: Some(2) });
        assert_eq!(k[6].0, TokenKind::Word { letter: b'Y', value: 0.5, decimals: Some(1) });
        assert_eq!(k[2].0, TokenKind::Word { letter: b'G', value: 1.0, decimals: None });
    }

    #[test]
    fn parallel_chunks_give_the_sequential_result() {
        let mut s = String::new();
        let mut i = 0u64;
        while s.len() < 5 << 20 {
            i += 1;
            s.push_str(&format!("N{i} G1 X{}.{} Y-{} (c{}) ; t\r\n", i % 997, i % 13, i % 89, i % 7));
            if i.is_multiple_of(1000) {
                s.push_str("\n%\n#1=2 X[#1]\n");
            }
        }
        s.push_str("G0 X1");
        let p = parse(&s);
        let (tokens, lines) = parse_range(&s, 0, s.len());
        assert_eq!(p.tokens, tokens);
        assert_eq!(p.lines, lines);
        assert_eq!(p.to_string(), s);
    }

    #[test]
    fn malformed_and_other_tokens() {
        let k = kinds("X1.2.3 Y- #1=2 X[#1+2] Z.");
        assert!(matches!(k[0].0, TokenKind::Malformed { letter: b'X' }));
        assert_eq!(k[0].1, "X1.2.3");
        assert!(matches!(k[2].0, TokenKind::Malformed { letter: b'Y' }));
        assert_eq!(k[4].0, TokenKind::Other);
        assert_eq!(k[4].1, "#1=2");
        assert_eq!(k[6].1, "X[#1+2]");
        assert_eq!(k[6].0, TokenKind::Other);
        assert!(matches!(k[8].0, TokenKind::Malformed { letter: b'Z' }));
    }
}
