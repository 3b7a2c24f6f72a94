//! Output helpers shared by the commands: JSON on stdout, progress bars on stderr, vector
//! formatting, and parsing of `X,Y,Z` option values.

use std::io::{IsTerminal, Write};

/// Print exactly one JSON object on stdout (pretty, one trailing newline).
pub fn print_json(value: &serde_json::Value) -> anyhow::Result<()> {
    // Built in memory and written with one call (stdout's line buffering would make one
    // system call per line of the pretty-printed object).
    let mut text = serde_json::to_vec_pretty(value)?;
    text.push(b'\n');
    let mut out = std::io::stdout().lock();
    out.write_all(&text)?;
    out.flush()?;
    Ok(())
}

/// Print a command's result: its JSON object on stdout with `--json`, else its human text (on
/// stderr when the text only summarises files written, so stdout stays clean).
pub fn emit(report: &impl truepos_io::report::Report, json: bool) -> anyhow::Result<()> {
    if json {
        return print_json(&report.to_json());
    }
    let text = report.text();
    if report.text_on_stderr() {
        eprint!("{text}");
    } else {
        let mut out = std::io::stdout().lock();
        out.write_all(text.as_bytes())?;
        out.flush()?;
    }
    Ok(())
}

/// A point or vector as a JSON array of three numbers.
pub fn v3(v: impl Into<[f64; 3]>) -> serde_json::Value {
    serde_json::json!(v.into())
}

/// A progress bar on stderr, hidden when stderr is not a terminal.
pub fn progress(len: u64, message: &str) -> indicatif::ProgressBar {
    if !std::io::stderr().is_terminal() {
        return indicatif::ProgressBar::hidden();
    }
    let pb = indicatif::ProgressBar::with_draw_target(Some(len), indicatif::ProgressDrawTarget::stderr());
    pb.set_style(
        indicatif::ProgressStyle::with_template("{msg} [{bar:40}] {pos}/{len} ({eta})")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    pb.set_message(message.to_string());
    pb
}

/// A size, feed, rate or limit: a finite number above zero (`--diameter-mm -25` and
/// `--diameter-mm=-25` both end here: every option accepts negative numbers as values, see
/// `cmd::command`).
pub fn positive(s: &str) -> Result<f64, String> {
    let v = number(s)?;
    if v > 0.0 {
        Ok(v)
    } else {
        Err(format!("must be positive (got {v})"))
    }
}

/// A radius, noise level or amount that may be zero but not negative.
pub fn non_negative(s: &str) -> Result<f64, String> {
    let v = number(s)?;
    if v >= 0.0 {
        Ok(v)
    } else {
        Err(format!("must be zero or positive (got {v})"))
    }
}

/// A finite number.
pub fn number(s: &str) -> Result<f64, String> {
    s.trim()
        .parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or_else(|| format!("'{}' is not a finite number", s.trim()))
}

/// A spinner with `message` on stderr while a step of unknown length runs (only when stderr is
/// a terminal; hidden otherwise, so logs and pipes stay clean). Finish it with
/// `finish_and_clear`.
pub fn spinner(message: &str) -> indicatif::ProgressBar {
    if !std::io::stderr().is_terminal() {
        return indicatif::ProgressBar::hidden();
    }
    let pb = indicatif::ProgressBar::with_draw_target(None, indicatif::ProgressDrawTarget::stderr());
    pb.set_style(
        indicatif::ProgressStyle::with_template("{spinner} {msg} ({elapsed})")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_spinner()),
    );
    pb.set_message(message.to_string());
    pb.enable_steady_tick(std::time::Duration::from_millis(120));
    pb
}

/// Parse `"x,y,z"` (for `--something-mm X,Y,Z` options).
pub fn parse_triple(s: &str) -> Result<[f64; 3], String> {
    let v = parse_list(s)?;
    if v.len() != 3 {
        return Err(format!("expected three comma-separated numbers X,Y,Z, got '{s}'"));
    }
    Ok([v[0], v[1], v[2]])
}

/// Parse `"a,b"`.
pub fn parse_pair(s: &str) -> Result<[f64; 2], String> {
    let v = parse_list(s)?;
    if v.len() != 2 {
        return Err(format!("expected two comma-separated numbers, got '{s}'"));
    }
    Ok([v[0], v[1]])
}

/// Parse a comma-separated list of finite numbers.
pub fn parse_list(s: &str) -> Result<Vec<f64>, String> {
    s.split(',')
        .map(|t| {
            t.trim()
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| format!("'{}' is not a finite number", t.trim()))
        })
        .collect()
}
