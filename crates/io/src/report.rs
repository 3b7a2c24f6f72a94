//! What a command hands back to be printed: one result, two renderings.
//!
//! Every task function of a capability crate (`truepos_comp::task`, `truepos_somac::align`, …)
//! returns a value that implements [`Report`]: the contract's JSON object (`--json`, one object
//! on stdout) and the human text. The binary only chooses between the two and prints; it holds
//! no output format of its own.
//!
//! Where the human text goes ([`Report::text_on_stderr`]): a command whose real output is a file
//! (a corrected point file, an influence map) writes its one-line summary to stderr, so stdout
//! stays clean for pipes; a command whose result *is* the text writes it to stdout.

/// A command's result, printable as the contract's JSON or as text for people.
pub trait Report {
    /// The contract's JSON object.
    fn to_json(&self) -> serde_json::Value;
    /// The human text (ends with a newline, or is empty when there is nothing to say).
    fn text(&self) -> String;
    /// True when the text is a summary of files written (printed on stderr).
    fn text_on_stderr(&self) -> bool {
        false
    }
}
