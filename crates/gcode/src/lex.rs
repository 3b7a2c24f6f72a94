//! Tokeniser: splits each line into tokens that tile it exactly.
//!
//! Token kinds: whitespace, comments (`( … )` and `; …`), words (a letter and a number:
//! `G1`, `X-12.5`, `N100`, `O1000`), `%`, malformed words (a letter followed by a number that
//! does not parse, such as `X1.2.3`), and anything else kept verbatim (`#1=2`, `X[#1+2]`,
//! `/` block delete, …).

use crate::{Line, Program};

/// What a token of a G-code line is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TokenKind {
    /// Spaces and tabs.
    Whitespace,
    /// `( … )`; `closed` is false when the line ends before `)`.
    ParenComment {
        /// Whether the comment ends with `)` on its line.
        closed: bool,
    },
    /// `; …` to the end of the line.
    SemicolonComment,
    /// A letter (upper-cased here) and its value. `decimals` is the number of digits written
    /// after the decimal point (`None` when there is no point).
    Word {
        /// The word's letter, upper case (ASCII).
        letter: u8,
        /// Its value, in program units.
        value: f64,
        /// Digits written after the decimal point (`None`: no point).
        decimals: Option<u8>,
    },
    /// A letter followed by something that looks like a number but is not one.
    Malformed {
        /// The word's letter, upper case (ASCII).
        letter: u8,
    },
    /// A letter whose value is an expression or parameter (`X[#1+2]`, `X#100`, `XSIN[30]`);
    /// `value` is filled in when the program's parameters determine it.
    Expr {
        /// The word's letter, upper case (ASCII).
        letter: u8,
        /// Its value, when the program's parameters determine it.
        value: Option<f64>,
    },
    /// A parameter setting, `#1=2` or `#<name> = [expr]`.
    Assign,
    /// `%`, the program start/end marker.
    Percent,
    /// Anything else, verbatim.
    Other,
}

/// One token: its kind and its byte range in the program's source.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Token {
    /// What the token is.
    pub kind: TokenKind,
    /// Byte offset of the token's first byte in the source.
    pub start: usize,
    /// Byte offset just past the token's last byte in the source.
    pub end: usize,
}

impl Token {
    /// The word's letter and value, if this is a word.
    /// An expression word counts once its value is known.
    pub fn word(&self) -> Option<(u8, f64)> {
        match self.kind {
            TokenKind::Word { letter, value, .. } => Some((letter, value)),
            TokenKind::Expr { letter, value: Some(value) } => Some((letter, value)),
            _ => None,
        }
    }
}

pub(crate) fn parse(source: String) -> Program {
    parse_reusing(source, Vec::new(), Vec::new()).0
}

/// [`parse`], filling `tokens` and `lines` (cleared first): a streamed program hands the
/// vectors of a finished piece back, so their memory is reused instead of allocated anew.
/// Also says whether every token is [plain](is_plain) (then there is nothing to evaluate).
pub(crate) fn parse_reusing(source: String, mut tokens: Vec<Token>, mut lines: Vec<Line>) -> (Program, bool) {
    // Large programs are tokenised in parallel chunks split at line ends.
    const CHUNK: usize = 1 << 20;
    let b = source.as_bytes();
    if b.len() <= 2 * CHUNK {
        tokens.clear();
        lines.clear();
        let plain = parse_range(&source, 0, b.len(), &mut tokens, &mut lines);
        return (Program { source, tokens, lines }, plain);
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
    let parts: Vec<(Vec<Token>, Vec<Line>, bool)> = bounds
        .par_windows(2)
        .map(|w| {
            let (mut t, mut l) = (Vec::new(), Vec::new());
            let plain = parse_range(&source, w[0], w[1], &mut t, &mut l);
            (t, l, plain)
        })
        .collect();
    let plain = parts.iter().all(|p| p.2);
    let n_tok = parts.iter().map(|p| p.0.len()).sum();
    let n_lines = parts.iter().map(|p| p.1.len()).sum();
    tokens.clear();
    lines.clear();
    tokens.reserve(n_tok);
    lines.reserve(n_lines);
    for (t, l, _) in parts {
        let base = tokens.len();
        lines.extend(l.into_iter().map(|mut line| {
            line.tokens = line.tokens.start + base..line.tokens.end + base;
            line
        }));
        tokens.extend(t);
    }
    (Program { source, tokens, lines }, plain)
}

/// A token that needs no evaluation and cannot fail the check: whitespace, a closed comment,
/// `%`, a word with a number (not an O word). A program of plain tokens sets no parameter,
/// has no expression, and passes [`Program::check`].
#[inline(always)]
fn is_plain(kind: &TokenKind) -> bool {
    match *kind {
        TokenKind::Word { letter, .. } => letter != b'O',
        TokenKind::Whitespace
        | TokenKind::ParenComment { closed: true }
        | TokenKind::SemicolonComment
        | TokenKind::Percent => true,
        _ => false,
    }
}

/// Tokenise the lines in `source[from..to]` (`from` at a line start, `to` after a line end or
/// at the end of the source), appending to `tokens` and `lines`. Offsets are absolute. Returns
/// whether every token is [plain](is_plain).
fn parse_range(source: &str, from: usize, to: usize, tokens: &mut Vec<Token>, lines: &mut Vec<Line>) -> bool {
    let b = &source.as_bytes()[..to];
    // A token takes one byte or more; three or more, mostly (`X1 ` is two tokens in three
    // bytes): room for a third of the bytes, so a piece of typical G-code never regrows. With
    // an eighth more, so that vectors reused from piece to piece (pieces of about the same
    // size, a few bytes more or less) are not reallocated at twice the size for a few bytes.
    reserve_slack(tokens, (to - from) / 3);
    reserve_slack(lines, (to - from) / 16 + 1);
    let mut pos = from;
    let mut plain = true;
    // One search over the whole range (lines are short: a call per line costs more).
    let mut ends = memchr::memchr_iter(b'\n', &b[from..]).map(|p| from + p);
    while pos < b.len() {
        let nl = ends.next();
        let (end, next) = match nl {
            Some(n) if n > pos && b[n - 1] == b'\r' => (n - 1, n + 1),
            Some(n) => (n, n + 1),
            None => (b.len(), b.len()),
        };
        let t0 = tokens.len();
        plain &= lex_line(source, pos, end, tokens);
        lines.push(Line { start: pos, end, next, tokens: t0..tokens.len() });
        pos = next;
    }
    plain
}

/// Room for `n` more elements in `v`, taken with an eighth to spare when it must grow.
fn reserve_slack<T>(v: &mut Vec<T>, n: usize) {
    if v.capacity() - v.len() < n {
        v.reserve(n + n / 8);
    }
}

#[inline]
fn memchr_nl(b: &[u8]) -> Option<usize> {
    memchr::memchr(b'\n', b)
}

/// Tokenise one line (`src[start..end]`, without its line ending) into `out`; whether every
/// token is [plain](is_plain).
fn lex_line(src: &str, start: usize, end: usize, out: &mut Vec<Token>) -> bool {
    let b = src.as_bytes();
    let mut i = start;
    let mut plain = true;
    while i < end {
        let c = b[i];
        let s = i;
        let kind = match c {
            b' ' | b'\t' | b'\r' => {
                let mut cr = false;
                while i < end && matches!(b[i], b' ' | b'\t' | b'\r') {
                    cr |= b[i] == b'\r';
                    i += 1;
                }
                // A carriage return with more text after it on the line: CR-only line ends,
                // which the check refuses (the line is not plain, so it is checked).
                if cr && i < end {
                    plain = false;
                }
                TokenKind::Whitespace
            }
            b'(' => {
                // Nested parentheses stay inside the comment: `(a (b) X99)` is one comment.
                let mut depth = 0usize;
                let mut closed = false;
                let mut cr = false;
                while i < end {
                    match b[i] {
                        b'(' => depth += 1,
                        // A carriage return inside: perhaps CR-only line ends (see below).
                        b'\r' => cr = true,
                        b')' => {
                            depth -= 1;
                            if depth == 0 {
                                i += 1;
                                closed = true;
                                break;
                            }
                        }
                        _ => {}
                    }
                    i += 1;
                }
                plain &= closed && !cr;
                TokenKind::ParenComment { closed }
            }
            b';' => {
                // A carriage return inside: perhaps CR-only line ends, which would make the
                // rest of the program this comment; the check decides (not plain).
                if memchr::memchr(b'\r', &b[i..end]).is_some() {
                    plain = false;
                }
                i = end;
                TokenKind::SemicolonComment
            }
            b'%' => {
                i += 1;
                TokenKind::Percent
            }
            c if c.is_ascii_alphabetic() => {
                i += 1;
                let letter = c.to_ascii_uppercase();
                let num_start = if i < end && (b[i] == b'+' || b[i] == b'-') { i + 1 } else { i };
                let numeric = num_start < end && (b[num_start].is_ascii_digit() || b[num_start] == b'.');
                if numeric {
                    match lex_number(b, i, end) {
                        Some((n_end, value, decimals, true))
                            if value.is_finite() && ends_value(b, n_end, end) =>
                        {
                            i = n_end;
                            plain &= letter != b'O';
                            TokenKind::Word { letter, value, decimals }
                        }
                        _ => {
                            i = skip_malformed(b, i, end);
                            plain = false;
                            TokenKind::Malformed { letter }
                        }
                    }
                } else if i < end && starts_expression(b, i, end) {
                    match crate::expr::parse_value(&b[i..end]) {
                        Ok((_, n)) if ends_value(b, i + n, end) => {
                            i += n;
                            plain = false;
                            TokenKind::Expr { letter, value: None }
                        }
                        _ => {
                            i = skip_malformed(b, i, end);
                            plain = false;
                            TokenKind::Malformed { letter }
                        }
                    }
                } else {
                    // A letter without a value (`X`, `Xabc`, `XNaN`): malformed up to the next
                    // space or comment.
                    i = skip_malformed(b, i, end);
                    plain = false;
                    TokenKind::Malformed { letter }
                }
            }
            b'#' => match crate::expr::parse_assignment(&b[i..end]) {
                Ok((_, _, n)) if ends_value(b, i + n, end) => {
                    i += n;
                    plain = false;
                    TokenKind::Assign
                }
                _ => {
                    i = skip_malformed(b, i + 1, end);
                    plain = false;
                    TokenKind::Other
                }
            },
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
                plain = false;
                TokenKind::Other
            }
        };
        // `plain` is kept in the arms above (cheaper than a test of every token's kind).
        debug_assert!(!plain || is_plain(&kind));
        out.push(Token { kind, start: s, end: i });
    }
    plain
}

/// Whether a word's value may end at `at`: end of line, a space, a comment or the next word.
/// `X1,5`, `X1e5`, `X1=2` are not values that end cleanly.
fn ends_value(b: &[u8], at: usize, end: usize) -> bool {
    if at >= end {
        return true;
    }
    match b[at] {
        b' ' | b'\t' | b'\r' | b'(' | b';' => true,
        b'e' | b'E' => {
            !b.get(at + 1).is_some_and(|c| c.is_ascii_digit() || *c == b'+' || *c == b'-' || *c == b'.')
        }
        c => c.is_ascii_alphabetic(),
    }
}

/// Skip a malformed value up to the next space or comment (or the line end).
fn skip_malformed(b: &[u8], from: usize, end: usize) -> usize {
    let mut i = from;
    let mut depth = 0i32;
    while i < end {
        match b[i] {
            b'[' => depth += 1,
            b']' => depth -= 1,
            b' ' | b'\t' | b'(' | b';' if depth <= 0 => break,
            _ => {}
        }
        i += 1;
    }
    // Never split a multi-byte character.
    while i < end && (b[i] & 0xC0) == 0x80 {
        i += 1;
    }
    i
}

/// Whether the text after a word letter starts an expression value: `[`, `#`, a sign before
/// one of those, or a function name followed by `[`.
fn starts_expression(b: &[u8], i: usize, end: usize) -> bool {
    let mut j = i;
    while j < end && (b[j] == b'+' || b[j] == b'-') {
        j += 1;
    }
    if j >= end {
        return false;
    }
    if b[j] == b'[' || b[j] == b'#' {
        return true;
    }
    let k0 = j;
    while j < end && b[j].is_ascii_alphabetic() {
        j += 1;
    }
    j > k0 && j < end && b[j] == b'['
}

/// A number after a word letter: `[+-]? (digits [. digits*] | . digits)`. Returns the end, the
/// value, the count of decimals, and whether the number is clean (not followed by more digits or
/// points, as in `1.2.3` or `1..2`, which make the word malformed).
fn lex_number(b: &[u8], start: usize, end: usize) -> Option<(usize, f64, Option<u8>, bool)> {
    // The common case in one pass: the exact fast path (≤ 19 digits, shared with every number
    // reader of truepos) reads the number, and a clean end (not more digits or points) is
    // checked after it. Everything else is scanned below.
    // The text after the line's end is passed too (the number cannot run into it: the line ends
    // at a `\r` or `\n`), so the reader can take eight bytes at a time up to the last number
    // of a line.
    if let Ok((v, n, decimals)) = truepos_math::decimal::decimal_prefix_decimals(&b[start..]) {
        let j = start + n;
        if j >= end || !(b[j].is_ascii_digit() || b[j] == b'.') {
            return Some((j, v, decimals.map(|d| d.min(255) as u8), true));
        }
    }
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
    // A number the fast path refused for what follows it (e.g. `X1.5E2`, an E word), on its own.
    if let Ok((v, n)) = truepos_math::decimal::decimal_prefix(&b[start..i]) {
        if start + n == i {
            return Some((i, v, decimals, true));
        }
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
        let p = parse(s.to_string());
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

    /// A piece of plain tokens is not evaluated (see `Program::parse_piece`): that is only
    /// right if such a piece sets nothing and passes the check; anything else is not plain.
    #[test]
    fn plain_tokens_need_no_evaluation() {
        for src in ["N10 G1 X1.5 Y-2 (c (nested)) ; t\r\n%\n\nG0 X.5\n", "g1x1y2\tz3\n", ""] {
            let (p, plain) = parse_reusing(src.to_string(), Vec::new(), Vec::new());
            assert!(plain, "{src:?}");
            assert!(p.check().is_ok(), "{src:?}");
        }
        for src in [
            "O1000\n",
            "#1=2\n",
            "G1 X[1+2]\n",
            "G1 X#1\n",
            "G1 X1.2.3\n",
            "G1 Xabc\n",
            "(open\n",
            "@\n",
            "/G1 X1\n",
            "\u{feff}G1 X1\n",
        ] {
            let (_, plain) = parse_reusing(src.to_string(), Vec::new(), Vec::new());
            assert!(!plain, "{src:?}");
        }
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
        let p = parse(s.clone());
        let (mut tokens, mut lines) = (Vec::new(), Vec::new());
        parse_range(&s, 0, s.len(), &mut tokens, &mut lines);
        assert_eq!(p.tokens, tokens);
        assert_eq!(p.lines, lines);
        assert_eq!(p.to_string(), s);
    }

    /// The fast path for short numbers gives the standard library's value bit for bit.
    #[test]
    fn short_numbers_parse_exactly() {
        let mut x = 0x9e3779b97f4a7c15u64;
        for _ in 0..200_000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let digits = (x % 15 + 1) as usize;
            let m = x >> 4;
            let txt = format!("{}", m % 10u64.pow(digits as u32));
            let p = (x >> 60) as usize % (txt.len() + 1);
            let sign = if x & 8 != 0 { "-" } else { "" };
            let s = format!("{sign}{}.{}", &txt[..p], &txt[p..]);
            let b = s.as_bytes();
            let (_, v, _, ok) = lex_number(b, 0, b.len()).unwrap();
            assert!(ok);
            let want: f64 = s.parse().unwrap();
            assert_eq!(v.to_bits(), want.to_bits(), "{s}");
        }
    }

    #[test]
    fn malformed_and_other_tokens() {
        let k = kinds("X1.2.3 Y- #1=2 X[#1+2] Z.");
        assert!(matches!(k[0].0, TokenKind::Malformed { letter: b'X' }));
        assert_eq!(k[0].1, "X1.2.3");
        assert!(matches!(k[2].0, TokenKind::Malformed { letter: b'Y' }));
        assert_eq!(k[4].0, TokenKind::Assign);
        assert_eq!(k[4].1, "#1=2");
        assert_eq!(k[6].1, "X[#1+2]");
        assert_eq!(k[6].0, TokenKind::Expr { letter: b'X', value: None });
        assert!(matches!(k[8].0, TokenKind::Malformed { letter: b'Z' }));
    }

    /// Words without a valid number are malformed tokens that keep their whole text.
    #[test]
    fn words_without_a_valid_number() {
        for (s, tok) in [
            ("G1 Xabc Y1", "Xabc"),
            ("G1 X Y1", "X"),
            ("G1 XNaN Y1", "XNaN"),
            ("G1 X1,5 Y1", "X1,5"),
            ("G1 X1e999 Y1", "X1e999"),
            ("G1 X1E5", "X1E5"),
            ("G1 X-inf", "X-inf"),
            ("G1 X[1+ Y1", "X[1+ Y1"),
            ("G1 X1=2", "X1=2"),
        ] {
            let k = kinds(s);
            let m: Vec<_> = k.iter().filter(|t| matches!(t.0, TokenKind::Malformed { .. })).collect();
            assert_eq!(m.len(), 1, "{s}: {k:?}");
            assert_eq!(m[0].1, tok, "{s}");
        }
        let big = format!("X1{}", "0".repeat(400));
        assert!(matches!(kinds(&big)[0].0, TokenKind::Malformed { .. }));
        // Words packed without spaces are still words.
        let k = kinds("G1X1.5Y-2F100");
        assert_eq!(k.len(), 4);
        assert!(k.iter().all(|t| matches!(t.0, TokenKind::Word { .. })));
    }

    #[test]
    fn nested_comments_are_one_token() {
        let k = kinds("G1 (a (b) X99) X1 ; c (d) X2");
        let texts: Vec<&str> = k.iter().map(|k| k.1.as_str()).collect();
        assert_eq!(texts, vec!["G1", " ", "(a (b) X99)", " ", "X1", " ", "; c (d) X2"]);
    }
}
