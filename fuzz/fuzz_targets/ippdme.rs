//! Fuzz target: the I++ DME layer never panics on any bytes a client (or a server) can send.
//!
//! - `parse_line` on every line; a parsed call prints to text that parses to the same call.
//! - The response parser and the data-item parser (the client's side) on the same lines.
//! - A whole session on the virtual CMM (a 25 mm sphere part) fed the input line by line:
//!   every line gets answers or a close, never a panic; a session that closes stops there.
//! - Part and machine TOML files (the server's configuration) from the same bytes.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::sync::Arc;
use truepos_plant::cmm::IppdmeCmm;
use truepos_ippdme::part::Part;
use truepos_ippdme::protocol::{parse_data_items, parse_line, Response};
use truepos_ippdme::server::{Flow, Session, Shared};
use truepos_ippdme::MachineConfig;

const PART: &str = "[[sphere]]\ncenter_mm = [100.0, 100.0, 50.0]\ndiameter_mm = 25.0\n";

fuzz_target!(|data: &[u8]| {
    for line in data.split(|&b| b == b'\n') {
        let line = line.strip_suffix(b"\r").unwrap_or(line);
        if let Ok((tag, call)) = parse_line(line) {
            let printed = format!("{tag} {call}");
            let (tag2, call2) = parse_line(printed.as_bytes()).expect("a printed call parses");
            assert_eq!(tag, tag2);
            assert_eq!(call.name, call2.name);
            assert_eq!(call.args.len(), call2.args.len());
        }
        if let Ok(text) = std::str::from_utf8(line) {
            let _ = Response::parse(text);
            let _ = parse_data_items(text);
        }
    }
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = Part::from_toml("fuzz.toml", text);
        let _ = MachineConfig::from_toml("fuzz.toml", text);
    }
    // Bound the session's work per input (each GoTo/PtMeas simulates motion).
    if data.len() > 4096 {
        return;
    }
    let config = MachineConfig::default();
    let part = Part::from_toml("part.toml", PART).ok();
    let shared = Arc::new(Shared::new(IppdmeCmm::new(&config, part), &config));
    let mut session = Session::new(shared);
    let mut out = Vec::new();
    for line in data.split(|&b| b == b'\n') {
        let line = line.strip_suffix(b"\r").unwrap_or(line);
        out.clear();
        if let Flow::Close = session.handle_line(line, &mut out) {
            break;
        }
        for r in &out {
            let _ = r.format();
        }
    }
    session.disconnect();
});
