//! Facts about text that every reader of line-based files needs, with no I/O: where a text's
//! lines end in a carriage return alone.
//!
//! Entry point: [`bare_carriage_return`], shared by the CSV/TOML/DMIS readers of `truepos-io`
//! and `truepos-dmis` and the G-code reader of `truepos-gcode`.

/// Where the first carriage return followed by more text on its line stands (1-based line and
/// column in characters): the lines end in a carriage return alone (classic Mac OS), so a
/// reader that splits at LF sees one line. A CR before the line's LF (CRLF, `\r\r\n`, trailing
/// blanks) is only a line end. `None` for a text without such a CR (one `memchr` pass).
pub fn bare_carriage_return(text: &str) -> Option<(usize, usize)> {
    let b = text.as_bytes();
    for p in memchr::memchr_iter(b'\r', b) {
        let end = memchr::memchr(b'\n', &b[p..]).map_or(b.len(), |n| p + n);
        if b[p + 1..end].iter().all(|c| matches!(c, b' ' | b'\t' | b'\r')) {
            continue;
        }
        let line_start = memchr::memrchr(b'\n', &b[..p]).map_or(0, |n| n + 1);
        return Some((
            memchr::memchr_iter(b'\n', &b[..p]).count() + 1,
            text[line_start..p].chars().count() + 1,
        ));
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_a_cr_followed_by_text_counts() {
        assert_eq!(bare_carriage_return("x\r\r\ny \r \n"), None);
        assert_eq!(bare_carriage_return("a\r\nb\n"), None);
        assert_eq!(bare_carriage_return("é\r\nab\rc"), Some((2, 3)));
        assert_eq!(bare_carriage_return("G90\rG0"), Some((1, 4)));
    }
}
